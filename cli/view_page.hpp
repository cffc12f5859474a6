// The page of rgbd-view / rgbd-capture --serve (cli/view_server.hpp): three.js points, orbit
// controls, play / pause / scrub, frame number, time and point count. Video mode fetches
// /api/info and /api/frame/N at the video's frame rate (frames the index marks as broken, or
// that the server cannot decode, are skipped); live mode fetches /api/live, the newest frame.
// #status carries data-frame, data-points and data-shown (frames drawn) for tests.
// kModelPage (rgbd-view MODEL.glb): the model of /model.glb through three.js's GLTFLoader,
// lit as rgbd-render draws (colour x (0.7 + 0.3 Lambert), light above-left of the camera,
// two-sided), seen from a three-quarter view (35 deg right of the front, 20 deg up; up and
// front from /api/info) and orbited with the mouse. #status carries data-loaded, data-triangles and
// data-textured (meshes with a texture) for tests.
#pragma once

namespace rgbd::cli {

inline constexpr const char* kViewPage = R"HTML(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>rgbd-view</title>
<style>
html,body{margin:0;height:100%;background:#202428;color:#e8e8e8;font:14px sans-serif;overflow:hidden}
#bar{position:absolute;left:0;right:0;bottom:0;padding:8px 12px;background:rgba(0,0,0,.55);
display:flex;gap:12px;align-items:center}
#scrub{flex:1}
button{min-width:64px}
#status{white-space:nowrap}
#msg{position:absolute;top:8px;left:12px}
</style></head><body>
<div id="msg">loading...</div>
<div id="bar"><button id="play">pause</button><input id="scrub" type="range" min="0" max="0" value="0">
<span id="status" data-frame="-1" data-points="0" data-shown="0">frame -</span></div>
<script src="three.min.js"></script>
<script src="OrbitControls.js"></script>
<script>
'use strict';
const msg = document.getElementById('msg'), statusEl = document.getElementById('status');
const playBtn = document.getElementById('play'), scrub = document.getElementById('scrub');
const renderer = new THREE.WebGLRenderer({antialias: false, preserveDrawingBuffer: true});
renderer.setPixelRatio(window.devicePixelRatio || 1);
renderer.setSize(window.innerWidth, window.innerHeight);
document.body.insertBefore(renderer.domElement, document.body.firstChild);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x202428);
const camera = new THREE.PerspectiveCamera(50, window.innerWidth / window.innerHeight, 0.01, 100);
camera.up.set(0, 0, 1);
const controls = new THREE.OrbitControls(camera, renderer.domElement);
const geometry = new THREE.BufferGeometry();
const material = new THREE.PointsMaterial({size: 3, sizeAttenuation: false, vertexColors: THREE.VertexColors});
const points = new THREE.Points(geometry, material);
scene.add(points);
let placed = false, playing = true, shown = 0, mode = 'video', frames = [], pos = 0, rate = 30;
let busy = false, lastStep = 0;

function decode(buf) {
  const head = new DataView(buf, 0, 16);
  const magic = String.fromCharCode(...new Uint8Array(buf, 0, 8));
  if (magic !== 'RGBDPTS1') throw new Error('not a frame');
  const n = head.getUint32(8, true), frame = head.getUint32(12, true);
  return {n, frame, xyz: new Float32Array(buf, 16, 3 * n), rgb: new Uint8Array(buf, 16 + 12 * n, 3 * n)};
}
function show(f, timeS) {
  geometry.dispose();  // frees the previous frame's GPU buffers
  geometry.setAttribute('position', new THREE.BufferAttribute(f.xyz, 3));
  geometry.setAttribute('color', new THREE.BufferAttribute(f.rgb, 3, true));
  geometry.computeBoundingSphere();
  if (!placed && f.n > 0) {
    const s = geometry.boundingSphere;
    controls.target.copy(s.center);
    camera.position.set(s.center.x, s.center.y - 3.2 * s.radius, s.center.z + 1.2 * s.radius);
    controls.update();
    placed = true;
  }
  shown += 1;
  statusEl.dataset.frame = f.frame; statusEl.dataset.points = f.n; statusEl.dataset.shown = shown;
  statusEl.textContent = 'frame ' + f.frame + (mode === 'video' ? ' / ' + frames.length : ' (live)') +
      '  t = ' + timeS.toFixed(3) + ' s  ' + f.n + ' points';
}
async function fetchFrame(url) {
  const r = await fetch(url, {cache: 'no-store'});
  if (r.status !== 200) return null;
  return {f: decode(await r.arrayBuffer()), time: Number(r.headers.get('X-Frame-Time-S') || 0)};
}
async function loadAt(k) {
  if (busy || frames.length === 0) return;
  busy = true;
  try {
    for (let tries = 0; tries < frames.length; ++tries) {
      const e = frames[k];
      const got = await fetchFrame('api/frame/' + e.frame);
      if (got) { pos = k; scrub.value = k; show(got.f, e.time_s); msg.textContent = ''; break; }
      k = (k + 1) % frames.length;  // a frame the server cannot decode: skipped
    }
  } finally { busy = false; }
}
async function liveStep() {
  if (busy) return;
  busy = true;
  try {
    const got = await fetchFrame('api/live');
    if (got) { show(got.f, got.time); msg.textContent = ''; }
  } catch (e) { msg.textContent = 'live: ' + e; }
  finally { busy = false; }
}
async function start() {
  const info = await (await fetch('api/info', {cache: 'no-store'})).json();
  mode = info.mode; rate = info.frame_rate_hz > 0 ? info.frame_rate_hz : 30;
  if (mode === 'video') {
    const t0 = info.frames.length ? info.frames[0].time_ns : 0;
    frames = info.frames.filter(e => e.ok).map(e => ({frame: e.frame, time_s: (e.time_ns - t0) * 1e-9}));
    scrub.max = Math.max(0, frames.length - 1);
    msg.textContent = frames.length ? '' : 'no playable frame';
    if (frames.length) await loadAt(0);
  } else {
    scrub.style.visibility = 'hidden';
    msg.textContent = 'waiting for the hub...';
  }
}
playBtn.onclick = () => { playing = !playing; playBtn.textContent = playing ? 'pause' : 'play'; };
scrub.oninput = () => { playing = false; playBtn.textContent = 'play'; loadAt(Number(scrub.value)); };
window.onresize = () => {
  camera.aspect = window.innerWidth / window.innerHeight; camera.updateProjectionMatrix();
  renderer.setSize(window.innerWidth, window.innerHeight);
};
function tick(now) {
  requestAnimationFrame(tick);
  if (playing && now - lastStep >= 1000 / rate) {
    lastStep = now;
    if (mode === 'video' && frames.length > 1) loadAt((pos + 1) % frames.length);
    else if (mode === 'live') liveStep();
  }
  controls.update();
  renderer.render(scene, camera);
}
start().then(() => requestAnimationFrame(tick)).catch(e => { msg.textContent = 'error: ' + e; });
</script></body></html>
)HTML";

inline constexpr const char* kModelPage = R"HTML(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>rgbd-view</title>
<style>
html,body{margin:0;height:100%;background:#202428;color:#e8e8e8;font:14px sans-serif;overflow:hidden}
#bar{position:absolute;left:0;right:0;bottom:0;padding:8px 12px;background:rgba(0,0,0,.55)}
#msg{position:absolute;top:8px;left:12px}
</style></head><body>
<div id="msg">loading...</div>
<div id="bar"><span id="status" data-loaded="0" data-triangles="0" data-textured="0">-</span></div>
<script src="three.min.js"></script>
<script src="OrbitControls.js"></script>
<script src="GLTFLoader.js"></script>
<script>
'use strict';
const msg = document.getElementById('msg'), statusEl = document.getElementById('status');
const renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
renderer.setPixelRatio(window.devicePixelRatio || 1);
renderer.setSize(window.innerWidth, window.innerHeight);
document.body.insertBefore(renderer.domElement, document.body.firstChild);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x202428);
const camera = new THREE.PerspectiveCamera(40, window.innerWidth / window.innerHeight, 0.001, 1000);
const controls = new THREE.OrbitControls(camera, renderer.domElement);
// colour x (0.7 + 0.3 max(0, n.l)), the light above-left of the camera: as rgbd-render.
scene.add(new THREE.AmbientLight(0xffffff, 0.7));
const sun = new THREE.DirectionalLight(0xffffff, 0.3);
sun.position.set(-0.35, 0.5, 1.0);
camera.add(sun); camera.add(sun.target);
scene.add(camera);

function place(object, upList, frontList) {
  const up = new THREE.Vector3().fromArray(upList || [0, 1, 0]).normalize();
  // Front: /api/info's, else the axis among +z, +x, -z, -x least aligned with up (as
  // rgbd-render without sensors).
  let front = frontList ? new THREE.Vector3().fromArray(frontList) : null;
  if (!front) for (const a of [[0, 0, 1], [1, 0, 0], [0, 0, -1], [-1, 0, 0]]) {
    const v = new THREE.Vector3().fromArray(a);
    if (!front || Math.abs(v.dot(up)) < Math.abs(front.dot(up)) - 1e-9) front = v;
  }
  front.addScaledVector(up, -front.dot(up)).normalize();
  const right = new THREE.Vector3().crossVectors(up, front);
  const az = 35 * Math.PI / 180, el = 20 * Math.PI / 180;
  const dir = front.clone().multiplyScalar(Math.cos(el) * Math.cos(az))
      .addScaledVector(right, Math.cos(el) * Math.sin(az)).addScaledVector(up, Math.sin(el));
  const sphere = new THREE.Box3().setFromObject(object).getBoundingSphere(new THREE.Sphere());
  const dist = 1.1 * sphere.radius / Math.sin(camera.fov * Math.PI / 360);
  camera.up.copy(up);
  camera.position.copy(sphere.center).addScaledVector(dir, dist);
  camera.near = dist / 100; camera.far = dist * 10; camera.updateProjectionMatrix();
  controls.target.copy(sphere.center);
  controls.update();
}
async function start() {
  const info = await (await fetch('api/info', {cache: 'no-store'})).json();
  const gltf = await new Promise((ok, fail) =>
      new THREE.GLTFLoader().load('model.glb', ok, undefined, fail));
  let triangles = 0, textured = 0;
  gltf.scene.traverse(o => {
    if (!o.isMesh) return;
    const old = o.material;
    if (old.map) { old.map.encoding = THREE.LinearEncoding; textured += 1; }
    o.material = new THREE.MeshLambertMaterial({map: old.map || null,
        vertexColors: old.vertexColors, side: THREE.DoubleSide});
    const g = o.geometry;
    triangles += (g.index ? g.index.count : g.attributes.position.count) / 3;
  });
  scene.add(gltf.scene);
  place(gltf.scene, info.up, info.front);
  statusEl.dataset.triangles = triangles; statusEl.dataset.textured = textured;
  statusEl.dataset.loaded = 1;
  statusEl.textContent = info.file + ': ' + triangles + ' triangles' +
      (textured ? ', textured' : ', vertex colours');
  msg.textContent = '';
}
window.onresize = () => {
  camera.aspect = window.innerWidth / window.innerHeight; camera.updateProjectionMatrix();
  renderer.setSize(window.innerWidth, window.innerHeight);
};
function tick() {
  requestAnimationFrame(tick);
  controls.update();
  renderer.render(scene, camera);
}
requestAnimationFrame(tick);
start().catch(e => { msg.textContent = 'error: ' + (e && e.message ? e.message : e); });
</script></body></html>
)HTML";

}  // namespace rgbd::cli
