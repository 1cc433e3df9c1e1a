// Editing classes in the web viewer (issue 70). The dataset's edits (`/edits/NAME`: the layer
// `myriad classify` keeps beside it) are given to every decode worker, which applies them to the
// pages it decodes (myriad_measure::edits compiled to WebAssembly; the surfaces ground edits
// name read by range requests), so the view shows the points as every command reads them.
// Where the server takes edits (`serve --edit`), "edit" draws a polygon by clicks on the data
// and "apply" gives the points in it a class or removes them (of the classes shown: hidden ones
// are left alone), as `myriad classify --polygon ... --to C` does: one change POSTed to the
// server, which adds it to the file as it is then, under the lock every editor takes (two
// viewers editing at once both keep their edits). "undo" and "redo" (Ctrl+Z, Ctrl+Y) are changes
// too. After each, the layer the server answers replaces the workers' and the nodes drawn are
// decoded again.
"use strict";

const editing = {
  loaded: false, editable: false, layer: null, polygon: [], changes: 0, applied: 0, done: "",
};
state.editing = editing;

function editsUrl() { return `/edits/${encodeURIComponent(state.dataset)}`; }

// The dataset's edits, applied before the first nodes are decoded (any decoded before are
// decoded again). A dataset being built has none yet (503: asked again when it is done); one the
// server cannot read them for is shown as stored, the reason said.
async function loadEdits() {
  try {
    const r = await fetch(editsUrl(), { cache: "no-store" });
    if (r.status === 503 || r.status === 404) {
      editing.editable = false;
      return;
    }
    if (!r.ok) throw new Error(`${editsUrl()}: HTTP ${r.status}: ${(await r.text()).trim()}`);
    const layer = await r.json();
    editing.editable = !!layer.editable;
    if (layer.edits.length) await useEdits(layer, nodes.size > 0);
    else editing.layer = layer;
  } catch (e) {
    editing.editable = false;
    error(`edits: ${e.message || e} (shown as stored)`);
  } finally {
    editing.loaded = true;
    editPanel();
  }
}

// Gives `layer` to every worker; `again`: the nodes drawn are decoded again (and the contours
// made again).
async function useEdits(layer, again) {
  const text = JSON.stringify({ myriad: "edits", version: 1, crs: layer.crs, edits: layer.edits,
    undone: layer.undone });
  const surfaces = new URL(`${editsUrl()}?surface=`, location.href).href;
  const workers = [selector, ...decoders];
  const answers = await Promise.all(workers.map((w) => call(w, { type: "edits", text, surfaces })));
  for (const a of answers) if (a.edits.error) throw new Error(a.edits.error);
  editing.layer = layer;
  // A terrain (`myriad ground`): colour by height above it.
  const scheme = document.getElementById("scheme");
  const ground = layer.edits.some((e) => e.ground);
  if (ground && scheme && ![...scheme.options].some((o) => o.value === "ramp:above_ground")) {
    scheme.querySelector("optgroup").prepend(new Option("above_ground", "ramp:above_ground"));
    if (settings.ramp && settings.ramp.name === "above_ground") scheme.value = "ramp:above_ground";
  }
  editing.applied += 1;
  if (again) {
    reload();
    if (state.contours && state.contours.on) makeContours(state.contours.interval).catch(() => {});
  }
}

// The classes shown, as `--classes` takes them (null: all).
function shownClasses() {
  if (!settings.hidden.size) return null;
  const runs = [];
  for (let c = 0; c < 256; c++) {
    if (settings.hidden.has(c)) continue;
    const last = runs[runs.length - 1];
    if (last && last[1] === c - 1) last[1] = c; else runs.push([c, c]);
  }
  return runs.map(([a, b]) => (a === b ? `${a}` : `${a}-${b}`)).join(",");
}

// One change (`{add: EDIT}`, `{undo: true}`, `{redo: true}`) made by the server; resolves with
// what it did. Changes are sent one after another, each answer applied before the next is sent.
let editsQueue = Promise.resolve();
function changeEdits(change) {
  const made = editsQueue.then(async () => {
    const r = await fetch(editsUrl(), { method: "POST", body: JSON.stringify(change),
      headers: { "Content-Type": "application/json" } });
    if (!r.ok) throw new Error(`HTTP ${r.status}: ${(await r.text()).trim()}`);
    const layer = await r.json();
    editing.changes += 1;
    editing.done = layer.done;
    await useEdits(layer, true);
    editPanel();
    return layer.done;
  });
  editsQueue = made.catch(() => {});
  return made;
}

// The polygon drawn given class `to` (a number), or its points removed (`to` = "remove").
function applyEdit(polygon, to) {
  const edit = { polygon: polygon.map((p) => [p[0], p[1]]) };
  const classes = shownClasses();
  if (classes) edit.classes = classes;
  if (to === "remove") edit.remove = true; else edit.to = Number(to);
  return changeEdits({ add: edit });
}

function editPoint(p) {
  editing.polygon.push(p);
  document.getElementById("edit-go").disabled = editing.polygon.length < 3;
  dirty = true;
}

// The polygon being drawn, as SVG over the view.
function editShapes() {
  const pts = editing.polygon.map(toScreen);
  if (pts.length < 2 || !pts.every((q) => q)) return "";
  const ring = mode === "edit" ? pts : [...pts, pts[0]];
  return `<polyline class="edit" points="${ring.map((q) => q.join(",")).join(" ")}" />`;
}

function editPanel() {
  const box = document.getElementById("edit");
  if (!box) return;
  const l = editing.layer;
  const n = l ? l.edits.length : 0;
  const status = document.getElementById("edit-status");
  status.textContent = editing.editable
    ? `${n} edit${n === 1 ? "" : "s"}${editing.done ? `; ${editing.done}` : ""}`
    : `${n} edit${n === 1 ? "" : "s"} shown; read-only: \`myriad serve --edit\` lets viewers edit`;
  document.getElementById("edit-start").disabled = !editing.editable;
  document.getElementById("edit-to").disabled = !editing.editable;
  document.getElementById("edit-undo").disabled = !editing.editable || !n;
  document.getElementById("edit-redo").disabled = !editing.editable || !(l && l.undone.length);
  document.getElementById("edit-go").disabled = !editing.editable || editing.polygon.length < 3;
}

// The classes an edit gives, named by the class scheme: the ASPRS table's (0 to 22) and any
// other the scheme names.
function editClasses() {
  const to = document.getElementById("edit-to");
  const was = to.value;
  const named = state.info.classes.filter((c) => c.class <= 22 || !/^user \d+$/.test(c.name));
  to.replaceChildren(...named.map((c) => new Option(`${c.class} ${c.name}`, String(c.class))),
    new Option("remove the points", "remove"));
  if (was) to.value = was;
}

function editUi() {
  // A static site has no server to keep edits.
  if (SITE) { document.getElementById("edit").style.display = "none"; return; }
  const to = document.getElementById("edit-to");
  editClasses();
  to.value = "7";
  const failed = (e) => { editing.problem = String(e.message || e); error(editing.problem); editPanel(); };
  document.getElementById("edit-start").onclick = () => {
    const on = mode !== "edit";
    editing.polygon = [];
    setMode(on ? "edit" : "pick");
    editPanel();
    dirty = true;
  };
  document.getElementById("edit-go").onclick = () => {
    const polygon = editing.polygon;
    editing.polygon = [];
    setMode("pick");
    applyEdit(polygon, to.value).catch(failed);
  };
  document.getElementById("edit-undo").onclick = () => changeEdits({ undo: true }).catch(failed);
  document.getElementById("edit-redo").onclick = () => changeEdits({ redo: true }).catch(failed);
  window.addEventListener("keydown", (e) => {
    const typing = ["INPUT", "TEXTAREA", "SELECT"].includes(e.target.tagName) || e.target.isContentEditable;
    if (!editing.editable || !(e.ctrlKey || e.metaKey) || typing) return;
    const k = e.key.toLowerCase();
    if (k === "z" && !e.shiftKey) { e.preventDefault(); changeEdits({ undo: true }).catch(failed); }
    if (k === "y" || (k === "z" && e.shiftKey)) { e.preventDefault(); changeEdits({ redo: true }).catch(failed); }
  });
  editPanel();
}
