// The web viewer's WebGL2 renderer (every browser with WebGL2; webgpu.js where WebGPU works).
// `makeWebGL2(canvas)` gives the renderer viewer.js draws with: upload, release, tree, draw.
"use strict";

function makeWebGL2(canvas) {
  const gl = canvas.getContext("webgl2", { antialias: false, preserveDrawingBuffer: true });
  if (!gl) return null;
  const TREE_WIDTH = 1024;
  const POINT_VS = `#version 300 es
  precision highp float; precision highp int; precision highp usampler2D;
  layout(location = 0) in vec3 pos;
  layout(location = 1) in vec4 colour;
  uniform mat4 vp;
  uniform vec2 size;
  uniform float spacing, focal, maxSize, fixedSize, side;
  uniform int node;
  uniform usampler2D tree;
  uniform vec4 clipMin, clipMax;
  out vec4 vColour;
  uvec4 entry(uint i) { return texelFetch(tree, ivec2(int(i & 1023u), int(i >> 10u)), 0); }
  uint ones(uint m) { uint n = 0u; for (int b = 0; b < 8; b++) n += (m >> uint(b)) & 1u; return n; }
  // draw.wgsl's point_pixels: the spacing of the finest drawn node around the point, as seen;
  // a lone point (its colour's alpha 0, as the module marks it) at most 3 pixels.
  float pointPixels(vec3 p, float w, bool alone) {
    if (fixedSize > 0.0) return clamp(round(fixedSize), 1.0, maxSize);
    float sp = spacing;
    if (node >= 0) {
      uint i = uint(node);
      vec3 lo = vec3(0.0);
      float s = side;
      float own = uintBitsToFloat(entry(i).z);
      float scale = own > 0.0 ? spacing / own : 1.0;
      for (int d = 0; d < 32; d++) {
        uvec4 e = entry(i);
        s *= 0.5;
        vec3 mid = lo + vec3(s);
        uint o = (p.x >= mid.x ? 1u : 0u) | (p.y >= mid.y ? 2u : 0u) | (p.z >= mid.z ? 4u : 0u);
        if ((e.x & (1u << o)) == 0u) break;
        i = e.y + ones(e.x & ((1u << o) - 1u));
        lo += vec3(float(o & 1u), float((o >> 1u) & 1u), float((o >> 2u) & 1u)) * s;
        float cs = uintBitsToFloat(entry(i).z);
        if (cs > 0.0) sp = cs * scale;
      }
    }
    float px = clamp(round(sp * focal / w), 1.0, maxSize);
    return alone ? min(px, 3.0) : px;
  }
  void main() {
    vColour = vec4(colour.rgb, 1.0);
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    gl_PointSize = 1.0;
    if (clipMin.w != 0.0) {
      bool inside = all(greaterThanEqual(pos, clipMin.xyz)) && all(lessThanEqual(pos, clipMax.xyz));
      if (inside == (clipMin.w == 2.0)) return;
    }
    vec4 clip = vp * vec4(pos, 1.0);
    if (clip.w <= 0.0) return;
    vec3 ndc = clip.xyz / clip.w;
    if (ndc.x < -1.0 || ndc.x >= 1.0 || ndc.y <= -1.0 || ndc.y > 1.0 || ndc.z < -1.0 || ndc.z > 1.0) return;
    // The square the native rasterizers cover (quads.wgsl): snapped to whole pixels.
    float s = pointPixels(pos, clip.w, colour.a < 0.5 && clipMax.w > 0.5);
    float fx = (ndc.x * 0.5 + 0.5) * size.x, fy = (0.5 - ndc.y * 0.5) * size.y;
    float x0 = floor(fx) - floor((s - 1.0) * 0.5), y0 = floor(fy) - floor((s - 1.0) * 0.5);
    gl_Position = vec4((x0 + 0.5 * s) / size.x * 2.0 - 1.0, 1.0 - (y0 + 0.5 * s) / size.y * 2.0, ndc.z, 1.0);
    gl_PointSize = s;
  }`;
  const POINT_FS = `#version 300 es
  precision highp float;
  in vec4 vColour;
  out vec4 outColour;
  void main() { outColour = vColour; }`;
  // edl.wgsl: each pixel darkened by how far it lies behind its 8 neighbours at `radius`, in log
  // eye depth.
  const EDL_VS = `#version 300 es
  void main() { vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2)); gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0); }`;
  const EDL_FS = `#version 300 es
  precision highp float;
  uniform sampler2D colourTex, depthTex;
  uniform float near, far, radius, strength;
  uniform int edl;
  out vec4 outColour;
  float eyeDepth(float z) { float n = z * 2.0 - 1.0; return 2.0 * near * far / (far + near - n * (far - near)); }
  void main() {
    ivec2 q = ivec2(gl_FragCoord.xy);
    ivec2 dim = textureSize(depthTex, 0);
    float z = texelFetch(depthTex, q, 0).r;
    vec4 c = texelFetch(colourTex, q, 0);
    if (z >= 1.0 || edl == 0) { outColour = vec4(c.rgb, 1.0); return; }
    float l = log2(eyeDepth(z));
    float sum = 0.0;
    for (int k = 0; k < 8; k++) {
      float a = float(k) * 0.78539816;
      ivec2 j = q + ivec2(round(vec2(cos(a), sin(a)) * radius));
      if (j.x < 0 || j.y < 0 || j.x >= dim.x || j.y >= dim.y) continue;
      float zj = texelFetch(depthTex, j, 0).r;
      if (zj < 1.0) sum += max(0.0, l - log2(eyeDepth(zj)));
    }
    outColour = vec4(c.rgb * exp(-sum / 8.0 * 300.0 * strength), 1.0);
  }`;

  function program(vs, fs) {
    const p = gl.createProgram();
    for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
      const s = gl.createShader(type);
      gl.shaderSource(s, src);
      gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
      gl.attachShader(p, s);
    }
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    const u = {};
    const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; i++) { const a = gl.getActiveUniform(p, i); u[a.name] = gl.getUniformLocation(p, a.name); }
    return { p, u };
  }

  const points = program(POINT_VS, POINT_FS);
  const edl = program(EDL_VS, EDL_FS);
  const treeTex = gl.createTexture();
  let fb = null;

  function framebuffer(w, h) {
    if (fb && fb.w === w && fb.h === h) return fb;
    const tex = (internal, format, type) => {
      const t = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, t);
      gl.texImage2D(gl.TEXTURE_2D, 0, internal, w, h, 0, format, type, null);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      return t;
    };
    if (fb) { gl.deleteTexture(fb.colour); gl.deleteTexture(fb.depth); gl.deleteFramebuffer(fb.f); }
    const colour = tex(gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE);
    const depth = tex(gl.DEPTH_COMPONENT32F, gl.DEPTH_COMPONENT, gl.FLOAT);
    const f = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, f);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, colour, 0);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.TEXTURE_2D, depth, 0);
    fb = { f, colour, depth, w, h };
    return fb;
  }

  const r = {
    kind: "webgl2",
    // Clip depth from -1 to 1.
    zeroToOne: false,
    upload(positions, colours) {
      const vao = gl.createVertexArray();
      gl.bindVertexArray(vao);
      const pb = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, pb);
      gl.bufferData(gl.ARRAY_BUFFER, positions, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(0);
      gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
      const cb = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, cb);
      gl.bufferData(gl.ARRAY_BUFFER, colours, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(1);
      gl.vertexAttribPointer(1, 4, gl.UNSIGNED_BYTE, true, 0, 0);
      gl.bindVertexArray(null);
      return { vao, buffers: [pb, cb] };
    },
    release(h) {
      gl.deleteVertexArray(h.vao);
      for (const b of h.buffers) gl.deleteBuffer(b);
    },
    // The drawn nodes' tree (DrawnTree entries, 4 u32 each) as an integer texture.
    tree(entries) {
      const n = Math.max(1, entries.length / 4);
      const rows = Math.ceil(n / TREE_WIDTH);
      const data = new Uint32Array(TREE_WIDTH * rows * 4);
      data.set(entries);
      gl.bindTexture(gl.TEXTURE_2D, treeTex);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32UI, TREE_WIDTH, rows, 0, gl.RGBA_INTEGER, gl.UNSIGNED_INT, data);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    },
    // One frame: `f` has width, height, focal, near, far, maxSize, fixedSize, edl (radius,
    // strength or null) and draws (handle, count, vp, spacing, node, side, clipMin, clipMax).
    draw(f) {
      const fbo = framebuffer(f.width, f.height);
      gl.bindFramebuffer(gl.FRAMEBUFFER, fbo.f);
      gl.viewport(0, 0, f.width, f.height);
      gl.clearColor(0, 0, 0, 1);
      gl.clearDepth(1);
      gl.enable(gl.DEPTH_TEST);
      gl.depthFunc(gl.LESS);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      gl.useProgram(points.p);
      const u = points.u;
      gl.uniform2f(u.size, f.width, f.height);
      gl.uniform1f(u.focal, f.focal);
      gl.uniform1f(u.maxSize, f.maxSize);
      gl.uniform1f(u.fixedSize, f.fixedSize);
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, treeTex);
      gl.uniform1i(u.tree, 0);
      for (const d of f.draws) {
        gl.uniformMatrix4fv(u.vp, false, d.vp);
        gl.uniform1f(u.spacing, d.spacing);
        gl.uniform1i(u.node, d.node);
        gl.uniform1f(u.side, d.side);
        gl.uniform4fv(u.clipMin, d.clipMin);
        gl.uniform4fv(u.clipMax, d.clipMax);
        gl.bindVertexArray(d.handle.vao);
        gl.drawArrays(gl.POINTS, 0, d.count);
      }
      gl.bindVertexArray(null);
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      gl.disable(gl.DEPTH_TEST);
      gl.useProgram(edl.p);
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, fbo.colour);
      gl.uniform1i(edl.u.colourTex, 0);
      gl.activeTexture(gl.TEXTURE1);
      gl.bindTexture(gl.TEXTURE_2D, fbo.depth);
      gl.uniform1i(edl.u.depthTex, 1);
      gl.uniform1f(edl.u.near, f.near);
      gl.uniform1f(edl.u.far, f.far);
      gl.uniform1f(edl.u.radius, f.edl ? f.edl.radius : 0);
      gl.uniform1f(edl.u.strength, f.edl ? f.edl.strength : 0);
      gl.uniform1i(edl.u.edl, f.edl ? 1 : 0);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
    },
  };
  r.tree([0, 0, 0, 0]);
  return r;
}
