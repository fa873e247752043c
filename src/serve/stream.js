// Footlight browser stream client (issue 17; byte layout in docs/stream.md).
//
// Connects to /api/stream. With WebGL2 it keeps every light's buffer in one
// layer of an RGB16F texture array and composites eq. 5, I = sum k_i *
// buffer_i, in the fragment shader (shaders/composite.frag) with the CPU
// reference's white balance, exposure, clipping and sRGB curve, only when a
// k vector or a buffer changed, at the display rate (requestAnimationFrame).
// Without WebGL2 (or with ?pictures in the page URL, or when the buffers
// would not fit) it asks for server-encoded pictures, shown in the <img>.
// If the WebSocket cannot open at all it falls back to polling
// /api/frame.png. window.__footlight exposes counters and the canvas pixels
// to tests.

const VERT = /*VERTEX*/;
const FRAG = /*FRAGMENT*/;

const MSG_HELLO = 1, MSG_BUFFER = 2, MSG_FRAME = 3, MSG_CLEARED = 4, MSG_PICTURE = 5, MSG_BODIES = 6, MSG_SET_MODE = 0x10;
const TILE = 16;
// Budget for the dense per-light layers (bytes); beyond it, pictures instead.
const LAYER_BUDGET = 1 << 30;

const probe = {
  counts: { hello: 0, buffer: 0, cleared: 0, frame: 0, picture: 0, bodies: 0, body_tiles: 0 },
  mode: 'connecting',
  frame: -1,
  composited: -1,
  composites: 0,
  busy: 0,
  dirty: false,
  webgl: null,
  error: null,
  pixels: () => null,
};
window.__footlight = probe;

function compile(gl, type, src) {
  const s = gl.createShader(type);
  gl.shaderSource(s, src);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}

class Compositor {
  constructor(canvas) {
    const gl = canvas.getContext('webgl2', { antialias: false, preserveDrawingBuffer: true, premultipliedAlpha: false });
    if (!gl) throw new Error('no WebGL2');
    this.gl = gl;
    this.canvas = canvas;
    probe.webgl = {
      renderer: gl.getParameter(gl.RENDERER),
      half_float_render: !!gl.getExtension('EXT_color_buffer_half_float'),
      float_render: !!gl.getExtension('EXT_color_buffer_float'),
      max_layers: gl.getParameter(gl.MAX_ARRAY_TEXTURE_LAYERS),
    };
    const p = gl.createProgram();
    gl.attachShader(p, compile(gl, gl.VERTEX_SHADER, VERT));
    gl.attachShader(p, compile(gl, gl.FRAGMENT_SHADER, FRAG));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    this.program = p;
    this.u = {};
    for (const n of ['u_buffers', 'u_k', 'u_lights', 'u_scale', 'u_display_scale', 'u_rolloff', 'u_height', 'u_body', 'u_kbody', 'u_has_bodies']) this.u[n] = gl.getUniformLocation(p, n);
    this.vao = gl.createVertexArray();
    this.buffers = null;
    this.kTex = null;
    this.bodyTex = null;
    this.kBodyTex = null;
  }

  // A float texture (RGBA32F, nearest) of w x h, filled with `fill` per texel.
  floatTexture(w, h, fill) {
    const gl = this.gl;
    const t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, w, h);
    for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, gl.NEAREST], [gl.TEXTURE_MAG_FILTER, gl.NEAREST]]) gl.texParameteri(gl.TEXTURE_2D, k, v);
    if (fill) {
      const data = new Float32Array(w * h * 4);
      for (let i = 0; i < w * h; i++) data.set(fill, 4 * i);
      gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, w, h, gl.RGBA, gl.FLOAT, data);
    }
    return t;
  }

  // Fixture body tiles (message 6): per pixel (base, glow, light) into the
  // body layer texture; base < 0: no body there (the composite shows).
  bodies(lights, tiles, indices, words) {
    const gl = this.gl, { width: w, height: h } = this;
    if (!this.bodyTex || this.bodyTex.w !== w || this.bodyTex.h !== h) {
      if (this.bodyTex) gl.deleteTexture(this.bodyTex.t);
      this.bodyTex = { t: this.floatTexture(w, h, [-1, 0, 0, 0]), w, h };
    }
    this.bodyLights = lights;
    const f = new Float32Array(words.buffer, words.byteOffset, words.length);
    const tilesX = Math.ceil(w / TILE);
    gl.bindTexture(gl.TEXTURE_2D, this.bodyTex.t);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 4);
    for (let t = 0; t < tiles; t++) {
      const x0 = (indices[t] % tilesX) * TILE, y0 = Math.floor(indices[t] / tilesX) * TILE;
      const cols = Math.min(TILE, w - x0), rows = Math.min(TILE, h - y0);
      if (cols <= 0 || rows <= 0) continue;
      const data = new Float32Array(cols * rows * 4);
      for (let y = 0; y < rows; y++) for (let x = 0; x < cols; x++) {
        const s = (t * TILE * TILE + y * TILE + x) * 3, d = (y * cols + x) * 4;
        data[d] = f[s]; data[d + 1] = f[s + 1]; data[d + 2] = words[s + 2]; data[d + 3] = 0;
      }
      gl.texSubImage2D(gl.TEXTURE_2D, 0, x0, y0, cols, rows, gl.RGBA, gl.FLOAT, data);
    }
  }

  // A fresh texture array for `lights` layers of width x height (hello).
  reset(width, height, lights) {
    const gl = this.gl;
    if (lights > probe.webgl.max_layers || width * height * 6 * lights > LAYER_BUDGET) return false;
    this.width = width; this.height = height; this.lights = lights;
    this.canvas.width = width; this.canvas.height = height;
    if (this.buffers) gl.deleteTexture(this.buffers);
    if (this.kTex) gl.deleteTexture(this.kTex);
    this.buffers = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.buffers);
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, 1, gl.RGB16F, width, height, Math.max(lights, 1));
    for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, gl.NEAREST], [gl.TEXTURE_MAG_FILTER, gl.NEAREST]]) gl.texParameteri(gl.TEXTURE_2D_ARRAY, k, v);
    const zero = new Uint16Array(width * height * 3);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    for (let i = 0; i < lights; i++) gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, i, width, height, 1, gl.RGB, gl.HALF_FLOAT, zero);
    this.kTex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.kTex);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, Math.max(lights, 1), 1);
    for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, gl.NEAREST], [gl.TEXTURE_MAG_FILTER, gl.NEAREST]]) gl.texParameteri(gl.TEXTURE_2D, k, v);
    this.scales = new Float32Array(lights).fill(1);
    if (this.bodyTex) gl.deleteTexture(this.bodyTex.t);
    this.bodyTex = null;
    this.bodyLights = 0;
    if (!this.noBodies) this.noBodies = this.floatTexture(1, 1, [-1, 0, 0, 0]);
    return true;
  }

  // One light's buffer: tile indices and f16 RGB tiles into its layer.
  upload(light, scale, tiles, indices, halfs) {
    if (light >= this.lights) return;
    const { width: w, height: h } = this;
    const tilesX = Math.ceil(w / TILE);
    const dense = new Uint16Array(w * h * 3);
    for (let t = 0; t < tiles; t++) {
      const x0 = (indices[t] % tilesX) * TILE, y0 = Math.floor(indices[t] / tilesX) * TILE;
      for (let y = 0; y < TILE && y0 + y < h; y++) {
        const cols = Math.min(TILE, w - x0);
        const src = (t * TILE * TILE + y * TILE) * 3;
        dense.set(halfs.subarray(src, src + cols * 3), ((y0 + y) * w + x0) * 3);
      }
    }
    this.layer(light, dense);
    this.scales[light] = scale;
  }

  clear(light) {
    if (light >= this.lights) return;
    this.layer(light, new Uint16Array(this.width * this.height * 3));
  }

  layer(light, data) {
    const gl = this.gl;
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.buffers);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, light, this.width, this.height, 1, gl.RGB, gl.HALF_FLOAT, data);
  }

  // Draws I = sum k_i * buffer_i with the frame's display settings.
  draw(k, display) {
    const gl = this.gl;
    const n = Math.min(this.lights, k.length / 4);
    const kk = new Float32Array(Math.max(this.lights, 1) * 4);
    for (let i = 0; i < n; i++) {
      for (let c = 0; c < 3; c++) kk[4 * i + c] = k[4 * i + c] * this.scales[i];
      kk[4 * i + 3] = k[4 * i + 3];
    }
    gl.bindTexture(gl.TEXTURE_2D, this.kTex);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, Math.max(this.lights, 1), 1, gl.RGBA, gl.FLOAT, kk);
    // Body glow: k_i of light i (the sum over the haze knots' entries i + jN, times the time factor).
    const nb = Math.max(this.bodyLights || 0, 1);
    const kb = new Float32Array(nb * 4);
    if (this.bodyLights) {
      for (let e = 0; e < k.length / 4; e++) {
        const i = e % this.bodyLights;
        for (let c = 0; c < 3; c++) kb[4 * i + c] += k[4 * e + c] * k[4 * e + 3];
      }
    }
    if (!this.kBodyTex || this.kBodyTex.n !== nb) {
      if (this.kBodyTex) gl.deleteTexture(this.kBodyTex.t);
      this.kBodyTex = { t: this.floatTexture(nb, 1, null), n: nb };
    }
    gl.bindTexture(gl.TEXTURE_2D, this.kBodyTex.t);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, nb, 1, gl.RGBA, gl.FLOAT, kb);
    gl.viewport(0, 0, this.width, this.height);
    gl.useProgram(this.program);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.buffers);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, this.kTex);
    gl.uniform1i(this.u.u_buffers, 0);
    gl.uniform1i(this.u.u_k, 1);
    gl.uniform1i(this.u.u_lights, n);
    gl.activeTexture(gl.TEXTURE2);
    gl.bindTexture(gl.TEXTURE_2D, this.bodyTex ? this.bodyTex.t : this.noBodies);
    gl.activeTexture(gl.TEXTURE3);
    gl.bindTexture(gl.TEXTURE_2D, this.kBodyTex.t);
    gl.uniform1i(this.u.u_body, 2);
    gl.uniform1i(this.u.u_kbody, 3);
    gl.uniform1i(this.u.u_has_bodies, this.bodyTex ? 1 : 0);
    gl.uniform1i(this.u.u_height, this.height);
    // As the reference: (white balance * exposure) * 65535 in f32.
    const f = Math.fround;
    gl.uniform3f(this.u.u_scale, ...[1, 2, 3].map(c => f(f(display[c] * display[0]) * 65535)));
    // The roll-off path: white balance * exposure, then display.rs
    // HighlightRolloff with the server's knee and white (white 0: clip).
    gl.uniform3f(this.u.u_display_scale, ...[1, 2, 3].map(c => f(display[c] * display[0])));
    gl.uniform3f(this.u.u_rolloff, display[4], display[5], display[5] > 0 ? 1 : 0);
    gl.bindVertexArray(this.vao);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
  }

  // The canvas as RGB rows top to bottom (tests).
  pixels() {
    const gl = this.gl, { width: w, height: h } = this;
    const rgba = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, rgba);
    const rgb = new Uint8Array(w * h * 3);
    for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) {
      const s = ((h - 1 - y) * w + x) * 4, d = (y * w + x) * 3;
      rgb[d] = rgba[s]; rgb[d + 1] = rgba[s + 1]; rgb[d + 2] = rgba[s + 2];
    }
    let bin = '';
    for (let i = 0; i < rgb.length; i += 0x8000) bin += String.fromCharCode.apply(null, rgb.subarray(i, i + 0x8000));
    return { width: w, height: h, frame: probe.composited, rgb: btoa(bin) };
  }
}

async function inflate(bytes) {
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('deflate-raw'));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

function poll(img) {
  probe.mode = 'polling';
  let n = 0;
  img.onload = img.onerror = () => setTimeout(() => { img.src = '/api/frame.png?n=' + (++n); }, 0);
  img.src = '/api/frame.png';
}

/** Starts the stream: buffers into `canvas` when WebGL2 works, else pictures into `img`. */
export function start(canvas, img) {
  let gl = null;
  const wantPictures = new URLSearchParams(location.search).has('pictures');
  if (!wantPictures) {
    try { gl = new Compositor(canvas); } catch (e) { probe.error = String(e); }
  }
  const show = buffers => { canvas.style.display = buffers ? '' : 'none'; img.style.display = buffers ? 'none' : ''; };
  show(!!gl);
  let mode = gl ? 'buffers' : 'pictures';
  const proto = location.protocol === 'https:' ? 'wss:' : 'ws:';
  const ws = new WebSocket(`${proto}//${location.host}/api/stream?mode=${mode}`);
  ws.binaryType = 'arraybuffer';
  let opened = false, k = null, display = null, dirty = false, lastUrl = null;
  const toPictures = () => {
    gl = null; mode = 'pictures'; show(false);
    if (ws.readyState === WebSocket.OPEN) ws.send(new Uint8Array([MSG_SET_MODE, 1]));
  };
  canvas.addEventListener('webglcontextlost', e => { e.preventDefault(); toPictures(); });
  let chain = Promise.resolve();
  const handle = async data => {
    const v = new DataView(data);
    const type = v.getUint8(0);
    if (type === MSG_HELLO) {
      probe.counts.hello++;
      const [w, h, lights] = [v.getUint32(4, true), v.getUint32(8, true), v.getUint32(12, true)];
      probe.mode = v.getUint8(2) === 0 ? 'buffers' : 'pictures';
      if (probe.mode === 'buffers' && gl && !gl.reset(w, h, lights)) toPictures();
    } else if (type === MSG_BUFFER && gl) {
      probe.counts.buffer++;
      const light = v.getUint32(4, true), tiles = v.getUint32(16, true), scale = v.getFloat32(20, true);
      const len = v.getUint32(24, true);
      let raw = new Uint8Array(data, 28, len);
      if (v.getUint8(1) & 1) raw = await inflate(raw);
      else raw = raw.slice();
      const indices = new Uint32Array(raw.buffer, raw.byteOffset, tiles);
      const halfs = new Uint16Array(raw.buffer, raw.byteOffset + tiles * 4, tiles * TILE * TILE * 3);
      gl.upload(light, scale, tiles, indices, halfs);
      dirty = true;
    } else if (type === MSG_CLEARED && gl) {
      probe.counts.cleared++;
      gl.clear(v.getUint32(4, true));
      dirty = true;
    } else if (type === MSG_BODIES && gl) {
      probe.counts.bodies++;
      const lights = v.getUint32(4, true), tiles = v.getUint32(8, true), len = v.getUint32(12, true);
      let raw = new Uint8Array(data, 16, len);
      if (v.getUint8(1) & 1) raw = await inflate(raw);
      else raw = raw.slice();
      probe.counts.body_tiles += tiles;
      const indices = new Uint32Array(raw.buffer, raw.byteOffset, tiles);
      const words = new Uint32Array(raw.buffer, raw.byteOffset + tiles * 4, tiles * TILE * TILE * 3);
      gl.bodies(lights, tiles, indices, words);
      dirty = true;
    } else if (type === MSG_FRAME) {
      probe.counts.frame++;
      if (gl) show(true); // back from a moving-camera picture to the composite
      const n = v.getUint32(4, true);
      probe.frame = Number(v.getBigUint64(8, true));
      display = [16, 20, 24, 28, 32, 36].map(o => v.getFloat32(o, true));
      const next = new Float32Array(data.slice(40, 40 + 16 * n));
      if (!k || k.length !== next.length || next.some((x, i) => x !== k[i]) || probe.composited < 0) dirty = true;
      k = next;
    } else if (type === MSG_PICTURE) {
      probe.counts.picture++;
      if (gl) show(false); // the camera moves: the server's preview, in the <img>
      probe.frame = Number(v.getBigUint64(4, true));
      if (lastUrl) URL.revokeObjectURL(lastUrl);
      lastUrl = URL.createObjectURL(new Blob([new Uint8Array(data, 12)], { type: 'image/png' }));
      img.src = lastUrl;
    }
  };
  ws.onopen = () => { opened = true; };
  ws.onmessage = e => {
    probe.busy++;
    chain = chain.then(() => handle(e.data)).catch(err => { probe.error = String(err); }).then(() => {
      probe.busy--;
      probe.dirty = dirty;
    });
  };
  ws.onclose = () => {
    if (!opened) { show(false); poll(img); return; }
    probe.mode = 'closed';
    setTimeout(() => start(canvas, img), 1000);
  };
  const frame = () => {
    if (dirty && gl && k && display) {
      dirty = false;
      probe.dirty = false;
      gl.draw(k, display);
      probe.composited = probe.frame;
      probe.composites++;
    }
    if (ws.readyState <= WebSocket.OPEN) requestAnimationFrame(frame);
  };
  requestAnimationFrame(frame);
  probe.pixels = () => (gl ? gl.pixels() : null);
}
