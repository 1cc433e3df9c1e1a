// The web viewer's WebGPU renderer, where the browser has WebGPU: the same frame as webgl2.js
// (and as the native quads path): each point a square of whole pixels (quads.wgsl), sized
// through the drawn nodes' tree by draw.wgsl's own point_pixels (the server sends the native
// shader; POINT_PIXELS below is replaced by that function), then eye-dome lighting (edl.wgsl).
// `makeWebGPU(canvas)` resolves to the renderer, or rejects where WebGPU does not work.
"use strict";

const POINTS_WGSL = `
struct Draw {
  vp: mat4x4<f32>,
  clip_min: vec4<f32>,
  clip_max: vec4<f32>,
  size: vec2<f32>,
  spacing: f32,
  focal: f32,
  max_size: f32,
  point_size: f32,
  side: f32,
  node: i32,
};
@group(0) @binding(0) var<uniform> u: Draw;
@group(0) @binding(1) var<storage, read> tree: array<vec4<u32>>;

struct Out {
  @builtin(position) pos: vec4<f32>,
  @location(0) colour: vec4<f32>,
};

const CORNERS = array<vec2<f32>, 6>(vec2<f32>(0.0, 0.0), vec2<f32>(1.0, 0.0), vec2<f32>(0.0, 1.0),
  vec2<f32>(0.0, 1.0), vec2<f32>(1.0, 0.0), vec2<f32>(1.0, 1.0));

POINT_PIXELS
@vertex
fn vs(@builtin(vertex_index) v: u32, @location(0) p: vec3<f32>, @location(1) colour: vec4<f32>) -> Out {
  var out: Out;
  out.pos = vec4<f32>(2.0, 2.0, 2.0, 1.0);
  // The module marks a lone point by its colour's alpha 0 (draw.wgsl's `lone`).
  out.colour = vec4<f32>(colour.rgb, 1.0);
  if (u.clip_min.w != 0.0) {
    let inside = all(p >= u.clip_min.xyz) && all(p <= u.clip_max.xyz);
    if (inside == (u.clip_min.w == 2.0)) {
      return out;
    }
  }
  let clip = u.vp * vec4<f32>(p, 1.0);
  if (clip.w <= 0.0) {
    return out;
  }
  let ndc = clip.xyz / clip.w;
  if (ndc.x < -1.0 || ndc.x >= 1.0 || ndc.y <= -1.0 || ndc.y > 1.0 || ndc.z < 0.0 || ndc.z > 1.0) {
    return out;
  }
  let fx = (ndc.x * 0.5 + 0.5) * u.size.x;
  let fy = (0.5 - ndc.y * 0.5) * u.size.y;
  let s = point_pixels(p, clip.w, u.spacing, bitcast<u32>(u.node), vec4<f32>(0.0, 0.0, 0.0, u.side), colour.a < 0.5 && u.clip_max.w > 0.5);
  let x0 = floor(fx) - floor((s - 1.0) * 0.5);
  let y0 = floor(fy) - floor((s - 1.0) * 0.5);
  let px = vec2<f32>(x0, y0) + CORNERS[v % 6u] * s;
  out.pos = vec4<f32>(px.x / u.size.x * 2.0 - 1.0, 1.0 - px.y / u.size.y * 2.0, ndc.z, 1.0);
  return out;
}

@fragment
fn fs(in: Out) -> @location(0) vec4<f32> {
  return in.colour;
}
`;

const EDL_WGSL = `
struct Edl { near: f32, far: f32, radius: f32, strength: f32, on: u32 };
@group(0) @binding(0) var colour_tex: texture_2d<f32>;
@group(0) @binding(1) var depth_tex: texture_depth_2d;
@group(0) @binding(2) var<uniform> e: Edl;

@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
  let p = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
  return vec4<f32>(p * 2.0 - 1.0, 0.0, 1.0);
}

// Eye depth from the depth buffer's 0..1 (the projection's inverse).
fn eye_depth(z: f32) -> f32 {
  let a = e.far / (e.far - e.near);
  let b = -e.far * e.near / (e.far - e.near);
  return b / (z - a);
}

@fragment
fn fs(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
  let q = vec2<i32>(pos.xy);
  let dim = vec2<i32>(textureDimensions(depth_tex));
  let z = textureLoad(depth_tex, q, 0);
  let c = textureLoad(colour_tex, q, 0);
  if (z >= 1.0 || e.on == 0u) {
    return vec4<f32>(c.rgb, 1.0);
  }
  let l = log2(eye_depth(z));
  var sum = 0.0;
  for (var k = 0; k < 8; k++) {
    let a = f32(k) * 0.78539816;
    let j = q + vec2<i32>(round(vec2<f32>(cos(a), sin(a)) * e.radius));
    if (j.x < 0 || j.y < 0 || j.x >= dim.x || j.y >= dim.y) {
      continue;
    }
    let zj = textureLoad(depth_tex, j, 0);
    if (zj < 1.0) {
      sum += max(0.0, l - log2(eye_depth(zj)));
    }
  }
  return vec4<f32>(c.rgb * exp(-sum / 8.0 * 300.0 * e.strength), 1.0);
}
`;

// `software`: take a software adapter too (SwiftShader and the like draw the six vertices of each
// point's square on the CPU: `myriad bench web` measured WebGL2's one-vertex points 2-5x faster
// there, so the viewer takes WebGPU by default only on a hardware adapter).
async function makeWebGPU(canvas, software) {
  if (!navigator.gpu) throw new Error("no navigator.gpu");
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) throw new Error("no WebGPU adapter");
  const info = adapter.info || {};
  const soft = adapter.isFallbackAdapter || info.isFallbackAdapter ||
    /swiftshader|llvmpipe|lavapipe|software/i.test(`${info.vendor} ${info.architecture} ${info.description}`);
  if (soft && !software) throw new Error(`a software adapter (${info.vendor} ${info.architecture})`);
  const device = await adapter.requestDevice();
  let lost = null;
  device.lost.then((i) => { lost = i.message || "device lost"; });
  const context = canvas.getContext("webgpu");
  if (!context) throw new Error("no WebGPU canvas context");
  const format = navigator.gpu.getPreferredCanvasFormat();
  context.configure({ device, format, alphaMode: "opaque" });

  const STRIDE = 256; // a draw's uniforms, at the dynamic-offset alignment
  const native = await (await fetch(VIEWER + "draw.wgsl")).text();
  const from = native.indexOf("fn point_pixels(");
  const to = native.indexOf("\n}\n", from);
  if (from < 0 || to < 0) throw new Error("draw.wgsl has no point_pixels");
  const pointsModule = device.createShaderModule({ code: POINTS_WGSL.replace("POINT_PIXELS", native.slice(from, to + 3)) });
  const edlModule = device.createShaderModule({ code: EDL_WGSL });
  const pointsLayout = device.createBindGroupLayout({
    entries: [
      { binding: 0, visibility: GPUShaderStage.VERTEX, buffer: { type: "uniform", hasDynamicOffset: true, minBindingSize: 128 } },
      { binding: 1, visibility: GPUShaderStage.VERTEX, buffer: { type: "read-only-storage" } },
    ],
  });
  const pointsPipeline = device.createRenderPipeline({
    layout: device.createPipelineLayout({ bindGroupLayouts: [pointsLayout] }),
    vertex: {
      module: pointsModule, entryPoint: "vs",
      buffers: [
        { arrayStride: 12, stepMode: "instance", attributes: [{ shaderLocation: 0, offset: 0, format: "float32x3" }] },
        { arrayStride: 4, stepMode: "instance", attributes: [{ shaderLocation: 1, offset: 0, format: "unorm8x4" }] },
      ],
    },
    fragment: { module: pointsModule, entryPoint: "fs", targets: [{ format: "rgba8unorm" }] },
    primitive: { topology: "triangle-list" },
    depthStencil: { format: "depth32float", depthWriteEnabled: true, depthCompare: "less" },
  });
  const edlPipeline = device.createRenderPipeline({
    layout: "auto",
    vertex: { module: edlModule, entryPoint: "vs" },
    fragment: { module: edlModule, entryPoint: "fs", targets: [{ format }] },
    primitive: { topology: "triangle-list" },
  });
  const edlUniforms = device.createBuffer({ size: 32, usage: GPUBufferUsage.UNIFORM | GPUBufferUsage.COPY_DST });
  let uniforms = null;
  let treeBuffer = null;
  let bindGroup = null;
  let targets = null;

  function setTree(entries) {
    const data = new Uint32Array(Math.max(4, entries.length));
    data.set(entries);
    if (!treeBuffer || treeBuffer.size < data.byteLength) {
      if (treeBuffer) treeBuffer.destroy();
      treeBuffer = device.createBuffer({ size: Math.max(256, data.byteLength * 2), usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_DST });
      bindGroup = null;
    }
    device.queue.writeBuffer(treeBuffer, 0, data);
  }

  function frameTargets(w, h) {
    if (targets && targets.w === w && targets.h === h) return targets;
    if (targets) { targets.colour.destroy(); targets.depth.destroy(); }
    const usage = GPUTextureUsage.RENDER_ATTACHMENT | GPUTextureUsage.TEXTURE_BINDING;
    const colour = device.createTexture({ size: [w, h], format: "rgba8unorm", usage });
    const depth = device.createTexture({ size: [w, h], format: "depth32float", usage });
    const edlGroup = device.createBindGroup({
      layout: edlPipeline.getBindGroupLayout(0),
      entries: [
        { binding: 0, resource: colour.createView() },
        { binding: 1, resource: depth.createView() },
        { binding: 2, resource: { buffer: edlUniforms } },
      ],
    });
    targets = { w, h, colour, depth, edlGroup };
    return targets;
  }

  const r = {
    kind: "webgpu",
    zeroToOne: true,
    upload(positions, colours) {
      // Both are whole multiples of 4 bytes, as writeBuffer wants.
      const make = (data) => {
        const b = device.createBuffer({ size: Math.max(16, data.byteLength), usage: GPUBufferUsage.VERTEX | GPUBufferUsage.COPY_DST });
        if (data.byteLength > 0) device.queue.writeBuffer(b, 0, data);
        return b;
      };
      return { positions: make(positions), colours: make(colours) };
    },
    release(h) {
      h.positions.destroy();
      h.colours.destroy();
    },
    tree: setTree,
    draw(f) {
      if (lost) throw new Error(`WebGPU: ${lost}`);
      if (canvas.width !== f.width || canvas.height !== f.height) return;
      const t = frameTargets(f.width, f.height);
      const need = Math.max(1, f.draws.length) * STRIDE;
      if (!uniforms || uniforms.size < need) {
        if (uniforms) uniforms.destroy();
        uniforms = device.createBuffer({ size: need * 2, usage: GPUBufferUsage.UNIFORM | GPUBufferUsage.COPY_DST });
        bindGroup = null;
      }
      if (!bindGroup) {
        bindGroup = device.createBindGroup({
          layout: pointsLayout,
          entries: [
            { binding: 0, resource: { buffer: uniforms, size: 128 } },
            { binding: 1, resource: { buffer: treeBuffer } },
          ],
        });
      }
      const data = new ArrayBuffer(need);
      f.draws.forEach((d, k) => {
        const fl = new Float32Array(data, k * STRIDE, 32);
        fl.set(d.vp, 0);
        fl.set(d.clipMin, 16);
        fl.set(d.clipMax, 20);
        fl.set([f.width, f.height, d.spacing, f.focal, f.maxSize, f.fixedSize, d.side], 24);
        new Int32Array(data, k * STRIDE + 124, 1)[0] = d.node;
      });
      device.queue.writeBuffer(uniforms, 0, data);
      device.queue.writeBuffer(edlUniforms, 0, new Float32Array([f.near, f.far, f.edl ? f.edl.radius : 0, f.edl ? f.edl.strength : 0]));
      device.queue.writeBuffer(edlUniforms, 16, new Uint32Array([f.edl ? 1 : 0]));
      const enc = device.createCommandEncoder();
      const pass = enc.beginRenderPass({
        colorAttachments: [{ view: t.colour.createView(), clearValue: [0, 0, 0, 1], loadOp: "clear", storeOp: "store" }],
        depthStencilAttachment: { view: t.depth.createView(), depthClearValue: 1, depthLoadOp: "clear", depthStoreOp: "store" },
      });
      pass.setPipeline(pointsPipeline);
      f.draws.forEach((d, k) => {
        pass.setBindGroup(0, bindGroup, [k * STRIDE]);
        pass.setVertexBuffer(0, d.handle.positions);
        pass.setVertexBuffer(1, d.handle.colours);
        pass.draw(6, d.count);
      });
      pass.end();
      const post = enc.beginRenderPass({
        colorAttachments: [{ view: context.getCurrentTexture().createView(), clearValue: [0, 0, 0, 1], loadOp: "clear", storeOp: "store" }],
      });
      post.setPipeline(edlPipeline);
      post.setBindGroup(0, t.edlGroup);
      post.draw(3);
      post.end();
      device.queue.submit([enc.finish()]);
    },
  };
  setTree([0, 0, 0, 0]);
  // A first frame, to find out whether this canvas works here (some set-ups lose the device
  // on the first submit).
  canvas.width = Math.max(1, canvas.width);
  canvas.height = Math.max(1, canvas.height);
  r.draw({ width: canvas.width, height: canvas.height, focal: 1, near: 1, far: 2, maxSize: 1, fixedSize: 1, edl: null, draws: [] });
  await device.queue.onSubmittedWorkDone();
  await new Promise((ok) => setTimeout(ok, 50));
  if (lost) throw new Error(`WebGPU: ${lost}`);
  return r;
}
