// Contours in the web viewer (issue 70): the lines of the terrain `myriad ground` found under the
// dataset (its ground edit's surface), every interval the panel gives, made by a decode worker
// (myriad_measure::contours::of_terrain in WebAssembly, the surface read by range requests, sampled
// on at most CONTOUR_CELLS cells) and drawn over the view at their elevations, every fifth
// brighter: what `view`'s "contours every" draws.
"use strict";

const CONTOUR_CELLS = 512 * 512;
const contours = { on: false, interval: 1, lines: [], made: 0, problem: null };
state.contours = contours;

// Makes the contours every `interval`; resolves with how many lines.
async function makeContours(interval) {
  const w = decoders.reduce((a, b) => (b.busy < a.busy ? b : a));
  w.busy += 1;
  try {
    const m = await call(w, { type: "contours", interval, cells: CONTOUR_CELLS });
    if (m.contours.error) throw new Error(m.contours.error);
    Object.assign(contours, { lines: m.contours.lines, interval, on: true, problem: null });
    contours.made += 1;
  } catch (e) {
    Object.assign(contours, { lines: [], problem: String(e.message || e) });
    throw e;
  } finally {
    w.busy -= 1;
    dirty = true;
  }
  return contours.lines.length;
}

// The lines as SVG over the view (broken where a vertex is behind the eye).
function contourShapes() {
  if (!contours.on) return "";
  let svg = "";
  let vertices = 0;
  const every = 5 * contours.interval;
  for (const c of contours.lines) {
    const index = Math.abs(c.z / every - Math.round(c.z / every)) < 1e-6;
    const cls = index ? "contour index" : "contour";
    const pts = [];
    for (let i = 0; i + 1 < c.points.length; i += 2) pts.push(toScreen([c.points[i], c.points[i + 1], c.z]));
    if (c.closed && pts.length) pts.push(pts[0]);
    let run = [];
    const flush = () => {
      if (run.length >= 2) svg += `<polyline class="${cls}" points="${run.join(" ")}" />`;
      run = [];
    };
    for (const q of pts) { if (q) run.push(q.join(",")); else flush(); }
    flush();
    vertices += pts.length;
    if (vertices > 100000) break;
  }
  return svg;
}

function contoursUi() {
  const box = document.getElementById("contours");
  const every = document.getElementById("contours-every");
  // A static site has no terrain (edits are kept by a server).
  if (SITE) { box.closest("div").style.display = "none"; return; }
  const run = () => {
    if (!box.checked) { contours.on = false; dirty = true; return; }
    makeContours(Number(every.value) || 1).catch((e) => error(`contours: ${e.message || e}`));
  };
  box.onchange = run;
  every.onchange = run;
}
