// Cross-sections in the web viewer: "profile" draws a section line by clicks on the data, "cut"
// cuts the profile of the original points within half the width of it, but for the hidden
// classes, in a decode worker (myriad_measure::profile compiled to WebAssembly, reading the
// pages the corridor meets by range requests: the points `myriad profile` and `view` cut), and
// shows it: distance along against height, coloured as the view. Two clicks in the picture
// measure between them (along, height, slope, straight: myriad_measure::profile::between); the
// picture saves as PNG, the points as CSV (the rows `myriad profile -o .csv` writes) and as LAZ
// (the server's /x/NAME?line=...).
"use strict";

const section = { line: [], width: null, result: null, csv: "", picks: [], between: null, cuts: 0 };
state.section = section;
const PROFILE_PICTURE = 640;

function sectionWidth() {
  if (section.width === null) {
    const i = state.info;
    const b = i.bounds;
    const spacing = Math.sqrt(((b[3] - b[0]) * (b[4] - b[1])) / Math.max(1, i.points));
    section.width = +(4 * spacing).toPrecision(3);
    document.getElementById("section-width").value = section.width;
  }
  return section.width;
}

function sectionPoint(p) {
  section.line.push(p);
  document.getElementById("cut").disabled = section.line.length < 2;
  dirty = true;
}

// Cuts along `line` (plan points) `width` wide; resolves with the summary.
async function cutProfile(line, width) {
  const w = decoders.reduce((a, b) => (b.busy < a.busy ? b : a));
  const panel = document.getElementById("profile");
  panel.querySelector(".summary").textContent = "cutting…";
  panel.style.display = "block";
  w.busy += 1;
  let m;
  try {
    m = await call(w, { type: "profile", line: line.flat(), width, picture: PROFILE_PICTURE,
      scheme: settings.scheme, hidden: [...settings.hidden] });
  } finally {
    w.busy -= 1;
  }
  const s = m.summary;
  section.result = s;
  section.csv = m.csv;
  section.picks = [];
  section.between = null;
  section.cuts += 1;
  section.image = s.frame ? new ImageData(new Uint8ClampedArray(m.rgba.buffer), s.frame.width, s.frame.height) : null;
  const half = width / 2;
  panel.querySelector(".summary").textContent = s.points
    ? `${s.points.toLocaleString()} points within ${half} ${s.units} of a ${s.length.toFixed(3)} ${s.units} line, elevation ${s.z[0].toFixed(3)} to ${s.z[1].toFixed(3)}, vertical exaggeration ${s.frame.exaggeration.toFixed(2)}`
    : "the corridor holds no point: the line is off the data, or the width too small";
  const q = new URLSearchParams();
  q.set("line", line.flat().join(","));
  q.set("width", width);
  panel.querySelector("a.laz").href = `/x/${encodeURIComponent(state.dataset)}?${q.toString().replace(/%2C/g, ",")}${filterQuery()}`;
  const csv = panel.querySelector("a.csv");
  if (csv.href) URL.revokeObjectURL(csv.href);
  csv.href = URL.createObjectURL(new Blob([section.csv], { type: "text/csv" }));
  csv.download = `${state.dataset.replace(/\.myr$/, "")}-profile.csv`;
  drawProfile();
  return s;
}

// The grid lines labelled over the picture (as `myriad profile -o .png` labels its axes):
// distances along its foot, elevations at its left, the unit, the vertical exaggeration.
function profileLabels(g, s) {
  const f = s.frame, grid = s.grid;
  if (!grid) return;
  const digits = (step) => Math.max(0, Math.ceil(-Math.log10(step)));
  const text = (t, x, y, align) => {
    g.textAlign = align;
    g.lineWidth = 3;
    g.strokeStyle = "rgba(250, 250, 250, 0.9)";
    g.strokeText(t, x, y);
    g.fillStyle = "rgb(40, 40, 40)";
    g.fillText(t, x, y);
  };
  g.font = "11px monospace";
  const bottom = f.margin + f.inner_h;
  grid.along.forEach((a, i) => {
    if (grid.along.length > 8 && i % 2 === 1) return;
    text(a.toFixed(digits(grid.steps[0])), f.margin + a * f.per_m, bottom - 3, "center");
  });
  for (const z of grid.z) {
    text(z.toFixed(digits(grid.steps[1])), 4, bottom - (z - f.z0) * f.per_m * f.exaggeration - 2, "left");
  }
  const ex = Math.abs(f.exaggeration - 1) > 0.005 ? `, vertical exaggeration ${f.exaggeration.toFixed(2)}x` : "";
  text(`distance along (${s.units})${ex}`, f.width - 4, 12, "right");
  text(`elevation (${s.units})`, 4, 12, "left");
}

function drawProfile() {
  const canvas = document.querySelector("#profile canvas");
  const s = section.result;
  if (!s || !s.frame) { canvas.width = 0; canvas.height = 0; return; }
  canvas.width = s.frame.width;
  canvas.height = s.frame.height;
  const g = canvas.getContext("2d");
  g.putImageData(section.image, 0, 0);
  profileLabels(g, s);
  const png = document.querySelector("#profile a.png");
  png.href = canvas.toDataURL("image/png");
  png.download = `${state.dataset.replace(/\.myr$/, "")}-profile.png`;
  g.fillStyle = g.strokeStyle = "rgb(200, 0, 120)";
  g.lineWidth = 2;
  const px = section.picks.map((q) => toProfilePx(q));
  for (const [x, y] of px) { g.beginPath(); g.arc(x, y, 4, 0, 2 * Math.PI); g.fill(); }
  if (px.length === 2) { g.beginPath(); g.moveTo(...px[0]); g.lineTo(...px[1]); g.stroke(); }
  document.querySelector("#profile .between").textContent = section.between ||
    "click two points of the profile to measure between them";
}

// The picture's frame (myriad_measure::profile::Frame) both ways.
function toProfilePx(q) {
  const f = section.result.frame;
  return [f.margin + q[0] * f.per_m, f.margin + f.inner_h - (q[1] - f.z0) * f.per_m * f.exaggeration];
}
function fromProfilePx(x, y) {
  const f = section.result.frame;
  return [(x - f.margin) / f.per_m, f.z0 + (f.margin + f.inner_h - y) / (f.per_m * f.exaggeration)];
}

async function profileClick(e) {
  if (!section.result || !section.result.frame) return;
  const c = e.target;
  const r = c.getBoundingClientRect();
  const x = ((e.clientX - r.left) * c.width) / r.width, y = ((e.clientY - r.top) * c.height) / r.height;
  if (section.picks.length >= 2) { section.picks = []; section.between = null; }
  section.picks.push(fromProfilePx(x, y));
  if (section.picks.length === 2) {
    const [a, b] = section.picks;
    section.between = (await call(decoders[0], { type: "between", a, b })).text;
  }
  drawProfile();
}

function profileUi() {
  const width = document.getElementById("section-width");
  width.onchange = () => { const v = Number(width.value); if (v > 0) section.width = v; };
  document.getElementById("section").onclick = () => {
    const on = mode !== "section";
    if (on) { section.line = []; sectionWidth(); }
    setMode(on ? "section" : "pick");
    document.getElementById("cut").disabled = section.line.length < 2;
  };
  document.getElementById("cut").onclick = () => {
    setMode("pick");
    cutProfile(section.line.map((p) => [p[0], p[1]]), sectionWidth()).catch((e) => error(String(e.message || e)));
  };
  document.querySelector("#profile canvas").addEventListener("click", (e) => profileClick(e).catch((x) => error(String(x.message || x))));
  document.querySelector("#profile .close").onclick = () => { document.getElementById("profile").style.display = "none"; };
}
