// Camera paths in the web viewer: "add view" (key J) adds the camera to the path being
// recorded, a view every few seconds; "remove last", "clear", its name; "save" keeps it with the
// dataset's saved work (`serve --edit`: the same "paths" `view` records and `render --path NAME`
// flies), "play" flies it or a saved one in the page. The curve is the one `render` flies: the
// selection worker's WebAssembly (myriad_measure::camera_path) gives its views at 60 a second.
"use strict";

const paths = { recording: { name: "path 1", views: [] }, playing: null, played: 0 };
state.paths = paths;

// Seconds between views: 0.1 to 600 (as the window takes them); a path stays within what the
// saved work's reader takes (10,000 views, a day).
function pathGap() { return Math.min(600, Math.max(0.1, Number(document.getElementById("path-gap").value) || 2)); }

function pathAdd() {
  const v = paths.recording.views;
  const time = v.length ? v[v.length - 1].time + pathGap() : 0;
  if (v.length >= 10000 || time > 86400) { error("a camera path holds at most 10,000 views and a day"); return; }
  v.push({ position: [...camera.position], target: [...camera.target], time });
  pathPanel();
}

// Plays `path` ({name, views}): its views at 60 a second from the worker, one a frame by time.
async function pathPlay(path) {
  const r = (await call(selector, { type: "path", path, fps: 60 })).path;
  if (r.error) { error(r.error); return; }
  paths.playing = { name: path.name, views: r.views, t0: performance.now() };
  pathPanel();
}

// Called each animation frame: the camera where the playing path is now.
function pathTick() {
  const p = paths.playing;
  if (!p) return;
  const i = Math.min(p.views.length - 1, Math.floor((performance.now() - p.t0) / 1000 * 60));
  const v = p.views[i];
  camera.position = v.slice(0, 3);
  camera.target = v.slice(3, 6);
  cameraMoved();
  if (i === p.views.length - 1) {
    paths.playing = null;
    paths.played += 1;
    pathPanel();
  }
}

function pathSave() {
  const rec = paths.recording;
  if (!work.editable || !rec.views.length) return;
  const copy = { name: rec.name.slice(0, 200), views: rec.views.map((v) => ({ ...v })) };
  work.doc.paths = (work.doc.paths || []).filter((p) => p.name !== rec.name).concat([copy]);
  saveWork().then(pathPanel);
}

function pathPanel() {
  const rec = paths.recording;
  const v = rec.views;
  const seconds = v.length ? v[v.length - 1].time - v[0].time : 0;
  document.getElementById("path-status").textContent = `${v.length} views, ${seconds.toFixed(1)} s` +
    (paths.playing ? ` | playing "${paths.playing.name}"` : "") +
    (!SITE && work.loaded && !work.editable ? "; read-only: `myriad serve --edit` keeps paths" : "");
  document.getElementById("path-save").disabled = !work.editable || !v.length;
  document.getElementById("path-play").disabled = !v.length;
  const saved = document.getElementById("path-saved");
  saved.textContent = "";
  for (const p of (work.doc && work.doc.paths) || []) {
    const row = document.createElement("div");
    const n = p.views.length;
    const s = n ? p.views[n - 1].time - p.views[0].time : 0;
    row.append(`${p.name} (${s.toFixed(1)} s) `);
    for (const [label, act] of [["play", () => pathPlay(p)],
      ["edit", () => { paths.recording = { name: p.name, views: p.views.map((x) => ({ ...x })) };
        document.getElementById("path-name").value = p.name; pathPanel(); }]]) {
      const b = document.createElement("button");
      b.textContent = label;
      b.onclick = act;
      row.append(b, " ");
    }
    saved.append(row);
  }
}

function pathUi() {
  document.getElementById("path-add").onclick = pathAdd;
  document.getElementById("path-undo").onclick = () => { paths.recording.views.pop(); pathPanel(); };
  document.getElementById("path-clear").onclick = () => { paths.recording.views = []; pathPanel(); };
  document.getElementById("path-name").onchange = (e) => { paths.recording.name = e.target.value.trim() || "path"; };
  document.getElementById("path-save").onclick = pathSave;
  document.getElementById("path-play").onclick = () => pathPlay(paths.recording);
  window.addEventListener("keydown", (e) => {
    const typing = ["INPUT", "TEXTAREA", "SELECT"].includes(e.target.tagName) || e.target.isContentEditable;
    if (typing || e.ctrlKey || e.metaKey || e.altKey || !camera) return;
    if (e.key === "j" || e.key === "J") pathAdd();
  });
  pathPanel();
}
