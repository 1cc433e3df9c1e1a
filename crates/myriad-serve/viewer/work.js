// Saved work in the web viewer: the dataset's annotations and measurements from `/work/NAME`
// (the sidecar `view` and `myriad annotate` keep beside it), drawn over the view as marks with
// their titles and figures, listed in the panel, and, where the server takes it (`serve
// --edit`), edited here and saved back (PUT): a click places an annotation, its title and text
// are typed in the panel, "go" shows it from its camera, a finished measurement is kept. The
// figures' labels are the server's (myriad_measure), not computed here.
"use strict";

const work = { loaded: false, editable: false, doc: null, saves: 0, failed: null };
state.work = work;

function workUrl() { return `/work/${encodeURIComponent(state.dataset)}`; }

async function loadWork() {
  const r = await fetch(workUrl(), { cache: "no-store" });
  if (!r.ok) { error(`${workUrl()}: HTTP ${r.status}: ${(await r.text()).trim()}`); return; }
  const doc = await r.json();
  work.editable = !!doc.editable;
  work.doc = doc;
  work.loaded = true;
  workPanel();
  pathPanel();
  dirty = true;
}

// PUT the work; the answer (with the server's labels) replaces it.
async function saveWork() {
  if (!work.editable) return;
  const d = work.doc;
  const body = JSON.stringify({
    myriad: "work", version: 1, crs: d.crs, annotations: d.annotations,
    measurements: d.measurements.map((m) => ({ kind: m.kind, points: m.points })),
    classes: d.classes, paths: d.paths,
  });
  try {
    const r = await fetch(workUrl(), { method: "PUT", body, headers: { "Content-Type": "application/json" } });
    if (!r.ok) throw new Error(`HTTP ${r.status}: ${(await r.text()).trim()}`);
    work.doc = await r.json();
    work.saves += 1;
    work.failed = null;
  } catch (e) {
    work.failed = `saving the work: ${e.message || e}`;
    error(work.failed);
  }
  workPanel();
  dirty = true;
}

function addAnnotation(p) {
  const a = work.doc.annotations;
  a.push({ position: [p.x, p.y, p.z], title: `annotation ${a.length + 1}`, text: "",
    camera: { position: [...camera.position], target: [p.x, p.y, p.z] } });
  work.open = a.length - 1;
  saveWork();
}

// A complete measurement kept with the work (where it can be saved).
function keepMeasurement(kind, points) {
  if (!work.editable || !work.doc) return;
  const n = TAKES[kind];
  if (n ? points.length !== n : points.length < (kind === "area" ? 3 : 2)) return;
  work.doc.measurements.push({ kind, points });
  saveWork();
}

// The panel: each annotation's title (editable), its view, its removal, the open one's text;
// each measurement's figure.
function workPanel() {
  const el = document.getElementById("work");
  el.textContent = "";
  if (!work.doc) return;
  const head = document.createElement("div");
  const button = document.createElement("button");
  button.id = "annotate";
  button.textContent = "annotate";
  button.disabled = !work.editable;
  button.title = work.editable ? "click a point to annotate it" : "read-only: myriad serve --edit saves work";
  button.classList.toggle("on", mode === "annotate");
  button.onclick = () => { setMode(mode === "annotate" ? "pick" : "annotate"); workPanel(); };
  head.append(button, work.editable ? " annotations (saved)" : " annotations (read-only)");
  el.append(head);
  work.doc.annotations.forEach((a, i) => {
    const row = document.createElement("div");
    row.className = "annotation-row";
    const title = document.createElement("input");
    title.className = "title";
    title.dataset.index = i;
    title.value = a.title;
    title.maxLength = 200;
    title.readOnly = !work.editable;
    title.onchange = () => { a.title = title.value; saveWork(); };
    const go = document.createElement("button");
    go.textContent = "go";
    go.disabled = !a.camera;
    go.onclick = () => { if (a.camera) myriad.setCamera({ position: [...a.camera.position], target: [...a.camera.target] }); };
    const open = document.createElement("button");
    open.textContent = "✎";
    open.onclick = () => { work.open = work.open === i ? null : i; workPanel(); };
    row.append(open, title, go);
    if (work.editable) {
      const del = document.createElement("button");
      del.textContent = "×";
      del.className = "remove";
      del.onclick = () => { work.doc.annotations.splice(i, 1); saveWork(); };
      row.append(del);
    }
    if (work.open === i) {
      const text = document.createElement("textarea");
      text.className = "text";
      text.dataset.index = i;
      text.value = a.text;
      text.readOnly = !work.editable;
      text.onchange = () => { a.text = text.value; saveWork(); };
      row.append(document.createElement("br"), text);
    }
    el.append(row);
  });
  work.doc.measurements.forEach((m, i) => {
    const row = document.createElement("div");
    row.className = "measurement-row";
    row.textContent = `${m.kind}: ${m.label || ""} `;
    if (work.editable) {
      const del = document.createElement("button");
      del.textContent = "×";
      del.onclick = () => { work.doc.measurements.splice(i, 1); saveWork(); };
      row.append(del);
    }
    el.append(row);
  });
}

// Where a point of the dataset is on the canvas, in CSS pixels (null: behind the eye).
function toScreen(p) {
  const [r, u, f] = basis(camera);
  const d = sub(p, camera.position);
  const z = dot(d, f);
  if (z <= 1e-9) return null;
  const h = canvas.clientHeight, w = canvas.clientWidth;
  const focal = h / (2 * Math.tan((camera.fov * Math.PI) / 360));
  return [w / 2 + (dot(d, r) * focal) / z, h / 2 - (dot(d, u) * focal) / z];
}

// The marks and labels over the view, redrawn with each frame.
function placeLabels() {
  const layer = document.getElementById("labels");
  if (!camera) { layer.textContent = ""; return; }
  const want = [];
  const doc = work.doc || { annotations: [], measurements: [] };
  for (const a of doc.annotations) want.push({ cls: "annotation", at: a.position, text: a.title });
  for (const m of doc.measurements) {
    want.push({ cls: "measurement", at: m.points[m.points.length - 1], text: m.label || m.kind, line: m.points, area: m.kind === "area" });
  }
  // The one being made.
  const now = state.measure.map((q) => q.position);
  if (now.length) {
    const m = state.measured;
    want.push({ cls: "measurement current", at: now[now.length - 1],
      text: m && m.complete && m.count === now.length ? m.label : `${now.length}`, line: now,
      area: measuring.kind === "area" });
  }
  while (layer.children.length > want.length + 1) layer.lastChild.remove();
  let svg = layer.querySelector("svg");
  if (!svg) {
    svg = document.createElementNS("http://www.w3.org/2000/svg", "svg");
    layer.append(svg);
  }
  svg.setAttribute("width", canvas.clientWidth);
  svg.setAttribute("height", canvas.clientHeight);
  let lines = "";
  want.forEach((w, i) => {
    let el = layer.children[i + 1];
    if (!el) { el = document.createElement("div"); layer.append(el); }
    el.className = `label ${w.cls}`;
    el.textContent = w.text;
    const s = toScreen(w.at);
    el.style.display = s ? "" : "none";
    if (s) { el.style.left = `${s[0]}px`; el.style.top = `${s[1]}px`; }
    if (w.line) {
      const pts = w.line.map(toScreen);
      if (pts.every((q) => q)) {
        const ring = w.area ? [...pts, pts[0]] : pts;
        lines += `<polyline points="${ring.map((q) => q.join(",")).join(" ")}" />`;
      }
    }
  });
  const cut = state.section ? state.section.line.map(toScreen) : [];
  if (cut.length >= 2 && cut.every((q) => q)) {
    lines += `<polyline class="section" points="${cut.map((q) => q.join(",")).join(" ")}" />`;
  }
  if (typeof contourShapes === "function") lines = contourShapes() + lines;
  if (typeof volumeShapes === "function") lines += volumeShapes();
  if (typeof editShapes === "function") lines += editShapes();
  svg.innerHTML = lines;
}
