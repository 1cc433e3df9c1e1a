// Photos and panoramas in the web viewer (`myriad photos` keeps them with a dataset; the server
// lists them at /photos/NAME and gives their images at /photos/NAME?file=FILE): a marker at each
// placed one; a click on it (or on the panel's list) opens it in the panel; "view from here"
// puts the camera at its pose (a pinhole camera's own field of view; a panorama's centre column
// over 90 degrees), and from there a pinhole photo is drawn over the points ("photo over the
// view" sets how opaque), so that the points show where the photo has them; a panorama as a
// sphere around the eye (each pixel of a half-resolution overlay takes the panorama's along its
// ray).
"use strict";

const photos = { list: [], open: null, atPose: null, loaded: false };
state.photos = photos;

// A vector of the camera's frame in the dataset's axes (quaternion w x y z).
function rotateBy(q, v) {
  const n = Math.hypot(...q), [w, x, y, z] = q.map((c) => c / n);
  return [
    (1 - 2 * (y * y + z * z)) * v[0] + 2 * (x * y - w * z) * v[1] + 2 * (x * z + w * y) * v[2],
    2 * (x * y + w * z) * v[0] + (1 - 2 * (x * x + z * z)) * v[1] + 2 * (y * z - w * x) * v[2],
    2 * (x * z - w * y) * v[0] + 2 * (y * z + w * x) * v[1] + (1 - 2 * (x * x + y * y)) * v[2],
  ];
}

// The camera at a photo's pose (as myriad_measure::photos::Photo::view).
function photoView(p) {
  if (!p.pose) return null;
  const r = p.pose.rotation, e = p.pose.position;
  const [fwd, up, fov] = p.kind === "pinhole"
    ? [rotateBy(r, [0, 0, 1]), rotateBy(r, [0, -1, 0]), 2 * Math.atan(p.height / 2 / p.focal[1]) * 180 / Math.PI]
    : [rotateBy(r, [1, 0, 0]), rotateBy(r, [0, 0, 1]), 90];
  return { position: [...e], target: e.map((v, i) => v + fwd[i]), up, fov };
}

function photoUrl(p) {
  return `/photos/${encodeURIComponent(state.dataset)}?file=${encodeURIComponent(p.file)}`;
}

async function loadPhotos() {
  const r = await fetch(`/photos/${encodeURIComponent(state.dataset)}`, { cache: "no-store" });
  if (!r.ok) { error(`photos: HTTP ${r.status}: ${(await r.text()).trim()}`); return; }
  photos.list = (await r.json()).photos;
  photos.loaded = true;
  photoPanel();
  dirty = true;
}

function openPhoto(i) {
  photos.open = i;
  photos.atPose = null;
  photoPanel();
}

function viewFromPhoto() {
  const v = photoView(photos.list[photos.open]);
  if (!v) return;
  Object.assign(camera, v);
  photos.atPose = [...v.position];
  cameraMoved();
}

function photoPanel() {
  const el = document.getElementById("photos");
  el.style.display = photos.list.length ? "" : "none";
  const list = el.querySelector(".list");
  list.textContent = "";
  photos.list.forEach((p, i) => {
    const a = document.createElement("a");
    a.href = "#";
    a.textContent = `${p.name} (${p.kind}${p.pose ? "" : ", not placed"})`;
    a.onclick = (e) => { e.preventDefault(); openPhoto(i); };
    list.append(a, " ");
  });
  const shown = el.querySelector(".shown");
  if (photos.open === null) { shown.textContent = ""; return; }
  const p = photos.list[photos.open];
  shown.innerHTML = "";
  const img = document.createElement("img");
  img.src = photoUrl(p);
  img.style.maxWidth = "320px";
  img.style.display = "block";
  const go = document.createElement("button");
  go.textContent = "view from here";
  go.disabled = !p.pose;
  go.onclick = viewFromPhoto;
  shown.append(`${p.name}: ${p.kind} ${p.width}x${p.height}${p.pose ? "" : ", not placed (no pose)"}`, img, go);
}

// Called after each frame: the markers, and the open photo over the view at its pose.
function photoMarks() {
  const layer = document.getElementById("photo-marks");
  if (!camera) return;
  while (layer.children.length > photos.list.length) layer.lastChild.remove();
  photos.list.forEach((p, i) => {
    let el = layer.children[i];
    if (!el) {
      el = document.createElement("div");
      el.className = "photo-mark";
      el.onclick = () => openPhoto(i);
      layer.append(el);
    }
    el.title = p.name;
    const s = p.pose && toScreen(p.pose.position);
    el.style.display = s ? "" : "none";
    if (s) { el.style.left = `${s[0]}px`; el.style.top = `${s[1]}px`; }
  });
  const over = document.getElementById("photo-over");
  const p = photos.open !== null ? photos.list[photos.open] : null;
  const at = photos.atPose && camera.position.every((v, i) => v === photos.atPose[i]);
  if (!at) photos.atPose = null;
  panoramaOver(at && p && p.kind === "spherical" ? p : null);
  const show = !!(at && p && p.kind === "pinhole");
  over.style.display = show ? "block" : "none";
  if (show) {
    const url = photoUrl(p);
    if (over.getAttribute("src") !== url) over.src = url;
    const h = canvas.clientHeight, w = h * p.width / p.height;
    over.style.height = `${h}px`; over.style.width = `${w}px`;
    over.style.left = `${(canvas.clientWidth - w) / 2}px`; over.style.top = "0px";
    over.style.opacity = document.getElementById("photo-opacity").value;
  }
}

// The panorama `p` as a sphere around the eye, over the view (none: hidden). Its pixels are
// read once (from the image the server gives: same origin).
function panoramaOver(p) {
  const c = document.getElementById("photo-sphere");
  if (!p) { c.style.display = "none"; return; }
  const url = photoUrl(p);
  if (!photos.pixels || photos.pixels.url !== url) {
    if (photos.loading === url) return;
    photos.loading = url;
    const img = new Image();
    img.onload = () => {
      // At most 4096 x 2048 read back (a browser's canvas has its limits).
      const t = document.createElement("canvas");
      t.width = Math.min(4096, img.naturalWidth); t.height = Math.min(2048, img.naturalHeight);
      const g = t.getContext("2d");
      g.drawImage(img, 0, 0, t.width, t.height);
      photos.pixels = { url, w: t.width, h: t.height, data: g.getImageData(0, 0, t.width, t.height).data };
      photos.loading = null;
      dirty = true;
    };
    img.onerror = () => { photos.loading = null; error(`${url}: not an image the browser reads`); };
    img.src = url;
    return;
  }
  const W = Math.max(1, Math.round(canvas.clientWidth / 2)), H = Math.max(1, Math.round(canvas.clientHeight / 2));
  if (c.width !== W || c.height !== H) { c.width = W; c.height = H; }
  const g = c.getContext("2d"), out = g.createImageData(W, H), px = photos.pixels;
  const [r, u, f] = basis(camera);
  const q = p.pose.rotation, inv = [q[0], -q[1], -q[2], -q[3]];
  const focal = H / (2 * Math.tan(camera.fov * Math.PI / 360));
  for (let y = 0; y < H; y++) {
    for (let x = 0; x < W; x++) {
      const dx = (x + 0.5 - W / 2) / focal, dy = -(y + 0.5 - H / 2) / focal;
      const d = rotateBy(inv, [0, 1, 2].map((i) => f[i] + r[i] * dx + u[i] * dy));
      const az = Math.atan2(d[1], d[0]), el = Math.atan2(d[2], Math.hypot(d[0], d[1]));
      const col = Math.min(px.w - 1, Math.max(0, Math.floor((Math.PI - az) / (2 * Math.PI) * px.w)));
      const row = Math.min(px.h - 1, Math.max(0, Math.floor((Math.PI / 2 - el) / Math.PI * px.h)));
      const a = (row * px.w + col) * 4, b = (y * W + x) * 4;
      out.data[b] = px.data[a]; out.data[b + 1] = px.data[a + 1]; out.data[b + 2] = px.data[a + 2]; out.data[b + 3] = 255;
    }
  }
  g.putImageData(out, 0, 0);
  c.style.display = "block";
  c.style.opacity = document.getElementById("photo-opacity").value;
}

function photosUi() {
  document.getElementById("photo-opacity").oninput = () => { dirty = true; };
  if (!SITE) loadPhotos().catch((e) => error(`photos: ${e.message || e}`));
  else photoPanel();
}
