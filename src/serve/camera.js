// Footlight camera controls (issue 16): orbit / pan / dolly / field of view
// (the same arithmetic as the window's, `control` in src/output/camera.rs)
// on the picture's container, a list of named views and "save view".
// A separate module so the page's picture element (an <img> today, a canvas
// later) can change without touching this file: the handlers sit on the
// picture's container, whatever element it holds.
//
//   drag (left button, one finger)        orbit around the target
//   drag with shift / right button / two fingers   pan
//   wheel, pinch                           dolly (towards the target)
//   alt + wheel                            field of view
//   "frame the rig"                        the named view of the rig and the stage
//
// The daemon confines every pose it is sent to the stage (issue 37: in the
// room, never behind a wall; src/scene/camera.rs): this page keeps the pose
// it asked for while a drag lasts, so orbiting back past a wall restores
// the distance, and takes the daemon's pose once the camera is still. The
// dolly stays within the daemon's distance range (`camera.limits` of
// /api/views), so the wheel has no dead travel beyond it.
//
// Writes go to POST /api/camera, at most one in flight (the newest pose
// replaces a waiting one), so a fast drag never queues requests. From
// another machine the daemon wants the token it printed at start: open the
// page as http://host:port/?token=… once, it is kept for the tab.

const params = new URLSearchParams(location.search);
if (params.get('token')) sessionStorage.setItem('footlight-token', params.get('token'));
const token = () => sessionStorage.getItem('footlight-token');

function headers() {
  const h = { 'content-type': 'application/json' };
  if (token()) h['x-footlight-token'] = token();
  return h;
}

// ---- vector helpers ----
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const mul = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const len = a => Math.hypot(a[0], a[1], a[2]);
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const norm = a => mul(a, 1 / (len(a) || 1));

let pose = null; // { position, target, fov_y }
let limits = { min: 0.2, max: 500 }; // the dolly's range, from the daemon's camera.limits
let sending = false, waiting = null;
// Tests read the page's pose here (the headless-browser drag test).
window.__footlightCamera = { get pose() { return pose; }, get limits() { return limits; } };
const panel = document.createElement('div');
panel.id = 'camera-panel';
panel.innerHTML = `
  <div style="margin:6px 0"><b>camera</b> <span id="camera-state" style="color:#999"></span></div>
  <select id="camera-views" style="max-width:220px"></select>
  <button id="camera-frame" title="the rig and the stage from a designer's seat">frame the rig</button>
  <input id="camera-name" placeholder="view name" size="12" maxlength="64">
  <button id="camera-save">save view</button>
  <div id="camera-error" style="color:#f88"></div>`;

function showError(text) {
  document.getElementById('camera-error').textContent = text || '';
}

async function send(body) {
  const r = await fetch('/api/camera', { method: 'POST', headers: headers(), body: JSON.stringify(body) });
  if (!r.ok) showError(`camera: ${r.status} ${await r.text()}`); else showError('');
  return r.ok;
}

// Sends the newest pose; one request in flight at a time.
async function pump() {
  if (sending || !waiting) return;
  sending = true;
  const body = waiting;
  waiting = null;
  try { await send(body); } catch (e) { showError('daemon not reachable'); }
  sending = false;
  pump();
}

function write() {
  if (!pose) return;
  waiting = { position: pose.position, target: pose.target, fov_y: pose.fov_y };
  if (pose.up) waiting.up = pose.up; // a rolled (glTF) camera keeps its roll
  pump();
}

// ---- camera moves ----
function orbit(dx, dy) {
  const off = sub(pose.position, pose.target);
  const r = len(off);
  let yaw = Math.atan2(off[0], off[2]);
  let pitch = Math.asin(Math.max(-1, Math.min(1, off[1] / r)));
  yaw -= dx * 0.008;
  pitch = Math.max(-1.5, Math.min(1.5, pitch + dy * 0.008));
  const o = [r * Math.cos(pitch) * Math.sin(yaw), r * Math.sin(pitch), r * Math.cos(pitch) * Math.cos(yaw)];
  pose.position = add(pose.target, o);
  delete pose.up; // a turntable about +Y: the horizon comes out level (as Pose::orbit)
}

function pan(dx, dy, height) {
  const fwd = norm(sub(pose.target, pose.position));
  let right = cross(fwd, pose.up || [0, 1, 0]);
  if (len(right) < 1e-6) right = cross(fwd, [0, 0, 1]);
  right = norm(right);
  const up = cross(right, fwd);
  // One pixel of drag moves the target by one pixel's width at its distance.
  const scale = 2 * len(sub(pose.target, pose.position)) * Math.tan((pose.fov_y * Math.PI) / 360) / Math.max(1, height);
  const move = add(mul(right, -dx * scale), mul(up, dy * scale));
  pose.position = add(pose.position, move);
  pose.target = add(pose.target, move);
}

function dolly(factor) {
  const off = sub(pose.position, pose.target);
  const r = Math.max(limits.min, Math.min(limits.max, len(off) * factor));
  pose.position = add(pose.target, mul(norm(off), r));
}

function zoom(factor) {
  pose.fov_y = Math.max(5, Math.min(120, pose.fov_y * factor));
}

// ---- input on the picture's container ----
function container() {
  const pic = document.getElementById('stage') || document.querySelector('canvas, img');
  return pic ? pic.parentElement : document.body;
}

function attach(el) {
  el.style.touchAction = 'none';
  const pointers = new Map();
  let mode = null;
  el.addEventListener('contextmenu', e => e.preventDefault());
  el.addEventListener('pointerdown', e => {
    if (e.target.closest && e.target.closest('#camera-panel')) return;
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
    mode = e.button === 2 || e.shiftKey ? 'pan' : 'orbit';
    if (el.setPointerCapture) try { el.setPointerCapture(e.pointerId); } catch (_) { /* synthetic events */ }
    e.preventDefault();
  });
  el.addEventListener('pointermove', e => {
    const last = pointers.get(e.pointerId);
    if (!last || !pose) return;
    const dx = e.clientX - last.x, dy = e.clientY - last.y;
    if (pointers.size >= 2) {
      // Two fingers: pan by the mean motion, pinch dollies.
      const pts = [...pointers.values()];
      const before = Math.hypot(pts[0].x - pts[1].x, pts[0].y - pts[1].y);
      pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
      const now = [...pointers.values()];
      const after = Math.hypot(now[0].x - now[1].x, now[0].y - now[1].y);
      pan(dx / 2, dy / 2, el.clientHeight);
      if (before > 0 && after > 0) dolly(before / after);
    } else {
      pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
      if (mode === 'pan') pan(dx, dy, el.clientHeight); else orbit(dx, dy);
    }
    write();
  });
  const up = e => { pointers.delete(e.pointerId); };
  el.addEventListener('pointerup', up);
  el.addEventListener('pointercancel', up);
  el.addEventListener('wheel', e => {
    if (!pose) return;
    e.preventDefault();
    const f = Math.exp(Math.max(-1, Math.min(1, e.deltaY * 0.001)));
    if (e.altKey) zoom(f); else dolly(f);
    write();
  }, { passive: false });
}

// ---- named views ----
async function refresh() {
  try {
    const v = await (await fetch('/api/views', { cache: 'no-store' })).json();
    const c = v.camera;
    if (c.limits) limits = { min: c.limits.min_distance, max: c.limits.max_distance };
    if (!sending && !waiting && c.phase === 'still') pose = c.current;
    if (!pose) pose = c.current;
    document.getElementById('camera-state').textContent =
      `${c.name ?? 'free'} · ${c.phase} · ${typeof c.stage === 'string' ? c.stage : 'refining'} · ` +
      `cache ${c.cache.entries} views, ${(c.cache.bytes / 1048576).toFixed(0)}/${(c.cache.budget_bytes / 1048576).toFixed(0)} MiB, ${c.cache.hits} hits`;
    const sel = document.getElementById('camera-views');
    const names = v.views.map(x => x.name);
    if (sel.dataset.names !== JSON.stringify(names)) {
      sel.dataset.names = JSON.stringify(names);
      sel.innerHTML = '<option value="">— views —</option>';
      for (const x of v.views) {
        const o = document.createElement('option');
        o.value = x.name;
        o.textContent = `${x.name} (${x.source})`;
        sel.appendChild(o);
      }
    }
  } catch (e) { /* the status poll reports an unreachable daemon */ }
  setTimeout(refresh, 500);
}

function setupPanel() {
  const place = document.getElementById('meta');
  (place ? place.parentElement : document.body).appendChild(panel);
  document.getElementById('camera-views').addEventListener('change', async e => {
    if (!e.target.value) return;
    if (await send({ view: e.target.value })) pose = null;
    e.target.value = '';
  });
  document.getElementById('camera-frame').addEventListener('click', async () => {
    if (await send({ view: 'frame the rig' })) pose = null;
  });
  document.getElementById('camera-save').addEventListener('click', async () => {
    const name = document.getElementById('camera-name').value;
    const r = await fetch('/api/views', { method: 'POST', headers: headers(), body: JSON.stringify({ name }) });
    showError(r.ok ? '' : `save: ${r.status} ${await r.text()}`);
  });
}

// A scripted drag for the headless browser test (?selftest=drag): the same
// pointer events a mouse sends, dispatched on the container.
async function selftest(el) {
  while (!pose) await new Promise(r => setTimeout(r, 20));
  const box = el.getBoundingClientRect();
  const at = (type, x) => el.dispatchEvent(new PointerEvent(type, {
    pointerId: 7, bubbles: true, button: 0, clientX: box.left + x, clientY: box.top + box.height / 2,
  }));
  at('pointerdown', 100);
  for (let i = 1; i <= 10; i++) { at('pointermove', 100 + 12 * i); await new Promise(r => setTimeout(r, 30)); }
  at('pointerup', 220);
}

setupPanel();
const el = container();
attach(el);
refresh();
if (params.get('selftest') === 'drag') selftest(el);
