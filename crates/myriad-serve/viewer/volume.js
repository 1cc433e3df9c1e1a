// Volumes in the web viewer: "volume" draws a polygon by clicks on the data, "measure" measures
// the volume of the points shown inside it above the rim's plane or an elevation, on cells of a
// size given or chosen from the spacing, in a decode worker (myriad_measure::volume compiled to
// WebAssembly, reading the pages the polygon meets by range requests: what `myriad volume` and
// `view` measure). The figures are the WebAssembly's; the view draws the polygon, the base under
// it and the grid (squares of cells at the surface's height, green for fill, red for cut).
"use strict";

const volume = { drawing: false, polygon: [], result: null, measured: 0 };
state.volume = volume;

function volumePoint(p) {
  volume.polygon.push(p);
  document.getElementById("volume-go").disabled = volume.polygon.length < 3;
  dirty = true;
}

// The base the panel asks for: null for the rim's plane, else an elevation.
function volumeBase() {
  if (document.getElementById("volume-base").value === "rim") return null;
  const z = document.getElementById("volume-z");
  if (z.value === "" && volume.polygon.length) z.value = Math.min(...volume.polygon.map((p) => p[2])).toFixed(3);
  return Number(z.value);
}

// Measures over `polygon` (plan points) down to `base` (null: the rim's plane) on cells of
// `cell` (0 or null: from the spacing); resolves with the result.
async function measureVolume(polygon, base, cell) {
  const out = document.getElementById("volume-result");
  out.textContent = "measuring…";
  const w = decoders.reduce((a, b) => (b.busy < a.busy ? b : a));
  w.busy += 1;
  let m;
  try {
    m = await call(w, { type: "volume", polygon: polygon.flat(), base: base === null ? 0 : 1,
      z: base === null ? 0 : base, cell: cell || 0, hidden: [...settings.hidden] });
  } catch (e) {
    out.textContent = String(e.message || e);
    volume.result = null;
    dirty = true;
    throw e;
  } finally {
    w.busy -= 1;
  }
  volume.result = m.volume;
  volume.measured += 1;
  out.textContent = m.volume.label.replace(/, /g, "\n");
  dirty = true;
  return m.volume;
}

// The polygon, the base and the grid as SVG over the view.
function volumeShapes() {
  let svg = "";
  const ring = (pts, cls, closed) => {
    if (pts.length < 2 || !pts.every((q) => q)) return "";
    const all = closed ? [...pts, pts[0]] : pts;
    return `<polyline class="${cls}" points="${all.map((q) => q.join(",")).join(" ")}" />`;
  };
  const r = volume.result;
  if (r) {
    for (const [x, y, h, top, fill] of r.blocks) {
      const c = [[x - h, y - h], [x + h, y - h], [x + h, y + h], [x - h, y + h]].map(([a, b]) => toScreen([a, b, top]));
      if (c.every((q) => q)) svg += `<polygon class="${fill ? "fill" : "cut"}" points="${c.map((q) => q.join(",")).join(" ")}" />`;
    }
    svg += ring(r.base.filter((q) => q).map(toScreen), "base", true);
  }
  svg += ring(volume.polygon.map(toScreen), "volume", !volume.drawing);
  return svg;
}

function volumeUi() {
  const button = document.getElementById("volume");
  const go = document.getElementById("volume-go");
  const base = document.getElementById("volume-base");
  const z = document.getElementById("volume-z");
  base.onchange = () => { z.style.display = base.value === "rim" ? "none" : ""; volumeBase(); };
  z.style.display = "none";
  button.onclick = () => {
    const on = mode !== "volume";
    if (on) { volume.polygon = []; volume.result = null; document.getElementById("volume-result").textContent = ""; }
    setMode(on ? "volume" : "pick");
    go.disabled = volume.polygon.length < 3;
    dirty = true;
  };
  go.onclick = () => {
    setMode("pick");
    const cell = Number(document.getElementById("volume-cell").value) || 0;
    measureVolume(volume.polygon.map((p) => [p[0], p[1]]), volumeBase(), cell)
      .catch((e) => error(String(e.message || e)));
  };
}
