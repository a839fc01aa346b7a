// amt's viewer: plays the GLBs that amt writes (data_tools/formats/gltf_export.h) side by side on one clock:
// mesh sequences (asset.extras.amt_format "mesh-sequence": frame 0 as POSITION, frame k as morph target k) and
// skinned animations ("skinned-animation": one skinned mesh, its joints and apparel handles as nodes, one
// animation with keyframe k at k / fps), both with the apparel mask as the COLOR_0 tint. Every file is drawn
// from its vertex positions at exact frames, computed on the CPU (a skinned animation's by three.js's own
// skinning, SkinnedMesh.getVertexPosition), so that every kind is measured and framed alike.
//
// What it plays comes from a manifest, viewer.json beside the page (or ?manifest=NAME):
//   {"format": "amt-viewer", "version": 1, "title": "...",
//    "groups": [{"title": "...", "items": [{"file": "x.glb", "label": "prediction", "role": "prediction"}, ...]}]}
// role is "prediction", "ground_truth", "skinning" or anything else (shown by its label). One group plays
// at a time (a select switches); with a "ground_truth" item, every other item of the same vertex count
// gets its PMD_a per frame (docs/evaluation.md, "Metrics": mean distance in cm over the ground truth's apparel
// vertices, no alignment) and over the clip.
//
// Query options: ?group=I (which group first), ?frame=K (start at frame K), ?paused=1.
//
// The page reports on itself for tests (tests/viewer/): window.amtViewerReport holds status ("loading",
// "ready" once every file of the group is loaded and drawn, "error" when anything failed), the files
// with their format (as played), frames, fps, vertices, apparel vertices, box (min and max over the clip) and
// a skinned animation's joint count, the number of meshes drawn, the current frame, the
// PMD_a readout (and pmdAFrames: each item's readout at every frame of the clip), the frame time, and every
// error (load failures, WebGL, uncaught exceptions and console.error messages).
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

// === The report

const report = {
  status: 'loading',
  title: '',
  group: 0,
  groups: 0,
  files: [],
  meshes: 0,
  framesLoaded: 0,
  frame: 0,
  frames: 0,
  pmdA: {},
  pmdAFrames: {},
  frameTimeMs: null,
  renderedFrames: 0,
  notes: [],
  errors: [],
};
window.amtViewerReport = report;

const errorBox = document.getElementById('errors');
function fail(message) {
  report.errors.push(String(message));
  report.status = 'error';
  errorBox.textContent = report.errors.join('\n');
}
const consoleError = console.error.bind(console);
console.error = (...args) => {
  fail('console.error: ' + args.map((a) => (a instanceof Error ? a.message : String(a))).join(' '));
  consoleError(...args);
};
window.addEventListener('error', (event) => fail('uncaught: ' + event.message));
window.addEventListener('unhandledrejection', (event) => fail('unhandled rejection: ' + (event.reason?.message ?? event.reason)));

// === Scene

const params = new URLSearchParams(location.search);
const view = document.getElementById('view');
let renderer;
try {
  renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
} catch (error) {
  fail('WebGL: cannot create a context (' + error.message + ')');
  throw error;
}
renderer.setPixelRatio(window.devicePixelRatio);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xf4f3f0);
scene.add(new THREE.HemisphereLight(0xffffff, 0x8d8a84, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(1.5, 3, 2.5);
scene.add(sun);
const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 100);
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = false;

function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h);
  camera.aspect = w / Math.max(1, h);
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

// === One played file: a mesh sequence or a skinned animation. Both are drawn as our own geometry whose
// positions are rewritten per frame (exact frames, no morph targets or bones uploaded to the GPU), and both
// give the positions of any frame (frameInto) for the PMD_a readout and the box.

// What the two kinds share: the apparel mask read from COLOR_0, the drawn mesh, and the box over every frame.
class Played {
  // `geometry`: the file's geometry (its vertex count, index and COLOR_0 are used); `format`: what the file is.
  constructor(item, gltf, geometry, format) {
    this.item = item;
    this.format = format;
    this.vertices = geometry.getAttribute('position').count;
    const extras = gltf.asset?.extras ?? {};
    this.fps = Number(extras.fps) > 0 ? Number(extras.fps) : 30;
    // The apparel mask: COLOR_0 is kApparelColor on apparel, kBodyColor elsewhere (blue above red).
    const color = geometry.getAttribute('color');
    this.mask = null;
    if (color) {
      this.mask = new Uint8Array(this.vertices);
      for (let i = 0; i < this.vertices; ++i) this.mask[i] = color.getZ(i) > color.getX(i) ? 1 : 0;
    }
    this.apparelVertices = this.mask ? this.mask.reduce((a, b) => a + b, 0) : null;
    // Our own geometry: positions rewritten per frame.
    const own = new THREE.BufferGeometry();
    this.positions = new THREE.BufferAttribute(new Float32Array(3 * this.vertices), 3);
    own.setAttribute('position', this.positions);
    if (color) own.setAttribute('color', color);
    own.setIndex(geometry.getIndex());
    this.mesh = new THREE.Mesh(own, new THREE.MeshStandardMaterial({
      color: color ? 0xffffff : 0xc8c4bc, vertexColors: Boolean(color), flatShading: true,
      side: THREE.DoubleSide, roughness: 0.85, metalness: 0,
    }));
    this.mesh.frustumCulled = false;
    this.shown = -1;
  }

  // The box over every frame, for the layout and the camera: `sample(k, visit)` calls visit(x, y, z) on some
  // vertices of frame k (a sample of the vertices is enough for a box).
  boxOver(sample) {
    this.box = new THREE.Box3();
    const p = new THREE.Vector3();
    for (let k = 0; k < this.frames; ++k) sample(k, (x, y, z) => this.box.expandByPoint(p.set(x, y, z)));
  }

  show(k) {
    if (k === this.shown) return;
    this.frameInto(k, this.positions.array);
    this.positions.needsUpdate = true;
    this.shown = k;
  }

  dispose() {}
}

// A mesh sequence: frame 0 and the per-frame deltas of the GLB's morph targets.
class Sequence extends Played {
  constructor(item, gltf) {
    let mesh = null;
    gltf.scene.traverse((o) => { if (!mesh && o.isMesh) mesh = o; });
    if (!mesh) throw new Error('no mesh in the file');
    const extras = gltf.asset?.extras ?? {};
    // Anything that is not a skinned animation is played as one: "morph targets" when it is not one either.
    super(item, gltf, mesh.geometry, extras.amt_format === 'mesh-sequence' ? 'mesh-sequence' : 'morph targets');
    const geometry = mesh.geometry;
    this.base = readFloats(geometry.getAttribute('position'));
    this.deltas = (geometry.morphAttributes.position ?? []).map(readFloats);
    this.frames = 1 + this.deltas.length;
    if (extras.amt_format !== 'mesh-sequence') {
      report.notes.push(item.file + ': not an amt mesh sequence (asset.extras.amt_format is ' +
                        JSON.stringify(extras.amt_format) + '): its morph targets are played as frames');
    }
    this.boxOver((k, visit) => {
      const d = k > 0 ? this.deltas[k - 1] : null;
      for (let j = 0; j < this.base.length; j += 21) {  // every 7th vertex
        visit(this.base[j] + (d ? d[j] : 0), this.base[j + 1] + (d ? d[j + 1] : 0), this.base[j + 2] + (d ? d[j + 2] : 0));
      }
    });
  }

  // Positions of frame k (3 N floats) into `out`.
  frameInto(k, out) {
    out.set(this.base);
    if (k <= 0) return out;
    const d = this.deltas[k - 1];
    for (let j = 0; j < out.length; ++j) out[j] += d[j];
    return out;
  }
}

// A skinned animation: the file's skinned mesh posed by its animation. Frame k is the animation at time
// k / fps (keyframe k) set on an AnimationMixer, its joints' world matrices updated, and every vertex skinned
// by three.js (SkinnedMesh.getVertexPosition: the sum of its weights times joint world matrix times inverse
// bind matrix, in the scene's frame since amt's skinned mesh sits at the root). Frames are computed when first
// shown or measured and kept.
class SkinnedAnimation extends Played {
  constructor(item, gltf) {
    let skinned = null;
    gltf.scene.traverse((o) => { if (!skinned && o.isSkinnedMesh) skinned = o; });
    if (!skinned) throw new Error('asset.extras.amt_format is "skinned-animation": expected a skinned mesh, found none');
    const clip = gltf.animations[0];
    if (!clip) throw new Error('asset.extras.amt_format is "skinned-animation": expected an animation, found none');
    super(item, gltf, skinned.geometry, 'skinned-animation');
    const version = gltf.asset?.extras?.amt_format_version;
    if (version !== 1) {
      report.notes.push(item.file + ': skinned animation of amt_format_version ' + JSON.stringify(version) +
                        ', this page reads version 1');
    }
    if (gltf.animations.length > 1) {
      report.notes.push(item.file + ': ' + gltf.animations.length + ' animations, the first (' +
                        JSON.stringify(clip.name) + ') is played');
    }
    this.root = gltf.scene;
    this.skinned = skinned;
    this.joints = skinned.skeleton.bones.length;
    this.mixer = new THREE.AnimationMixer(this.root);
    this.action = this.mixer.clipAction(clip);
    this.action.play();
    // Keyframe k at k / fps: the last at the clip's duration.
    this.frames = Math.max(1, Math.round(clip.duration * this.fps) + 1);
    this.cache = new Array(this.frames);
    this.posed = -1;
    const v = new THREE.Vector3();
    this.boxOver((k, visit) => {
      this.pose(k);
      for (let i = 0; i < this.vertices; i += 7) {
        skinned.getVertexPosition(i, v);
        visit(v.x, v.y, v.z);
      }
    });
  }

  // The skeleton at frame k.
  pose(k) {
    if (k === this.posed) return;
    this.action.time = k / this.fps;
    this.mixer.update(0);  // evaluates every channel at action.time
    // Rotations are stored as normalized SHORT components: back to unit quaternions.
    for (const bone of this.skinned.skeleton.bones) bone.quaternion.normalize();
    this.root.updateMatrixWorld(true);
    this.skinned.skeleton.update();
    this.posed = k;
  }

  // Positions of frame k (3 N floats) into `out`.
  frameInto(k, out) {
    let frame = this.cache[k];
    if (!frame) {
      this.pose(k);
      frame = new Float32Array(3 * this.vertices);
      const v = new THREE.Vector3();
      for (let i = 0; i < this.vertices; ++i) {
        this.skinned.getVertexPosition(i, v);
        frame[3 * i] = v.x, frame[3 * i + 1] = v.y, frame[3 * i + 2] = v.z;
      }
      this.cache[k] = frame;
    }
    out.set(frame);
    return out;
  }

  dispose() {
    this.mixer.stopAllAction();
    this.mixer.uncacheRoot(this.root);
    this.cache = [];
  }
}

// The played form of a loaded GLB, by its asset.extras.amt_format.
function played(item, gltf) {
  if (gltf.asset?.extras?.amt_format === 'skinned-animation') return new SkinnedAnimation(item, gltf);
  return new Sequence(item, gltf);
}

function readFloats(attribute) {
  if (!attribute.isInterleavedBufferAttribute && attribute.array instanceof Float32Array &&
      attribute.array.length === attribute.count * 3) {
    return attribute.array;
  }
  const out = new Float32Array(attribute.count * 3);
  for (let i = 0; i < attribute.count; ++i) {
    out[3 * i] = attribute.getX(i), out[3 * i + 1] = attribute.getY(i), out[3 * i + 2] = attribute.getZ(i);
  }
  return out;
}

// Mean distance in cm between frame k of `a` and of the ground truth `gt` over the ground truth's apparel
// vertices (all vertices when it has no mask).
function distanceCm(a, gt, k, scratchA, scratchB) {
  const pa = a.frameInto(Math.min(k, a.frames - 1), scratchA), pb = gt.frameInto(Math.min(k, gt.frames - 1), scratchB);
  let sum = 0, n = 0;
  for (let i = 0; i < gt.vertices; ++i) {
    if (gt.mask && !gt.mask[i]) continue;
    const j = 3 * i;
    sum += Math.hypot(pa[j] - pb[j], pa[j + 1] - pb[j + 1], pa[j + 2] - pb[j + 2]);
    ++n;
  }
  return n > 0 ? 100 * sum / n : NaN;
}

// === The group being played

const loader = new GLTFLoader();
let manifest = null;
let sequences = [];
let groupTitle = '';
let loadGeneration = 0;
let clock = 0;  // seconds into the clip
let playing = params.get('paused') !== '1';
let speed = 1;
let comparisons = [];  // {sequence, gt, perFrame: Float64Array, mean}
const labels = document.getElementById('labels');
const slider = document.getElementById('slider');
const readout = document.getElementById('readout');

function clipFrames() { return sequences.reduce((m, s) => Math.max(m, s.frames), 0); }
function clipFps() { return sequences.length ? sequences[0].fps : 30; }
function currentFrame() { return Math.min(clipFrames() - 1, Math.floor(clock * clipFps() + 1e-6)); }

async function loadGroup(index) {
  const generation = ++loadGeneration;
  for (const s of sequences) { scene.remove(s.mesh); s.mesh.geometry.dispose(); s.mesh.material.dispose(); s.dispose(); }
  sequences = [];
  comparisons = [];
  report.pmdAFrames = {};
  labels.replaceChildren();
  const group = manifest.groups[index];
  report.group = index;
  report.status = report.errors.length ? 'error' : 'loading';
  report.files = group.items.map((item) => ({ file: item.file, label: item.label ?? item.file, role: item.role ?? '' }));
  groupTitle = group.title ?? '';
  document.getElementById('title').textContent = [manifest.title, groupTitle].filter(Boolean).join(' · ');
  const results = await Promise.allSettled(group.items.map((item) => loader.loadAsync(item.file)));
  if (generation !== loadGeneration) return;
  const loaded = [];
  results.forEach((result, k) => {
    const entry = report.files[k];
    if (result.status === 'rejected') {
      entry.error = String(result.reason?.message ?? result.reason);
      fail(group.items[k].file + ': cannot load: ' + entry.error);
      return;
    }
    try {
      const s = played({ ...group.items[k], label: entry.label, role: entry.role }, result.value);
      entry.frames = s.frames, entry.vertices = s.vertices, entry.apparelVertices = s.apparelVertices, entry.fps = s.fps;
      entry.format = s.format, entry.box = { min: s.box.min.toArray(), max: s.box.max.toArray() };
      if (s.joints !== undefined) entry.joints = s.joints;
      loaded.push(s);
    } catch (error) {
      entry.error = error.message;
      fail(group.items[k].file + ': ' + error.message);
    }
  });
  sequences = loaded;
  report.meshes = sequences.length;
  report.framesLoaded = sequences.reduce((sum, s) => sum + s.frames, 0);
  report.frames = clipFrames();
  layout();
  compare();
  slider.max = String(Math.max(0, clipFrames() - 1));
  const start = Number(params.get('frame'));
  clock = Number.isFinite(start) && start > 0 ? Math.min(start, clipFrames() - 1) / clipFps() : 0;
  draw();
  if (sequences.length === 0 && report.errors.length === 0) fail('the group has no file to play');
  report.status = report.errors.length ? 'error' : 'ready';
}

// Side by side along x in the manifest's order, each on its own slot, all framed by the camera.
function layout() {
  if (sequences.length === 0) return;
  const size = new THREE.Vector3(), centre = new THREE.Vector3();
  let width = 0;
  for (const s of sequences) width = Math.max(width, s.box.getSize(size).x);
  const spacing = width + Math.max(0.25, 0.3 * width);
  const union = new THREE.Box3();
  sequences.forEach((s, k) => {
    s.box.getCenter(centre);
    s.mesh.position.set((k - (sequences.length - 1) / 2) * spacing - centre.x, 0, 0);
    scene.add(s.mesh);
    union.union(s.box.clone().translate(s.mesh.position));
    const label = document.createElement('div');
    labels.appendChild(label);
    s.label = label;
  });
  union.getSize(size);
  union.getCenter(centre);
  const vfov = THREE.MathUtils.degToRad(camera.fov);
  const fitHeight = size.y / (2 * Math.tan(vfov / 2));
  const fitWidth = size.x / (2 * Math.tan(vfov / 2) * camera.aspect);
  const distance = 1.05 * Math.max(fitHeight, fitWidth) + 0.35 * size.z;
  controls.target.copy(centre);
  // From the front and the side (characters face +z): the apparel behind them shows beside the body.
  camera.position.set(centre.x + 0.6 * distance, centre.y + 0.2 * distance, centre.z + 0.8 * distance);
  camera.near = distance / 100, camera.far = distance * 20;
  camera.updateProjectionMatrix();
  controls.update();
  const grid = scene.getObjectByName('ground') ?? new THREE.GridHelper(1, 10, 0xb9b5ad, 0xd9d6cf);
  grid.name = 'ground';
  grid.scale.setScalar(Math.max(size.x, size.z) * 1.4);
  grid.position.set(centre.x, union.min.y, centre.z);
  scene.add(grid);
}

// PMD_a of every item against the group's ground truth, per frame and over the clip.
function compare() {
  const gt = sequences.find((s) => s.item.role === 'ground_truth');
  if (!gt) return;
  if (!gt.mask) report.notes.push(gt.item.file + ': no apparel tint (COLOR_0): the readout is PMD over all vertices');
  const a = new Float32Array(3 * gt.vertices), b = new Float32Array(3 * gt.vertices);
  for (const s of sequences) {
    if (s === gt) continue;
    if (s.vertices !== gt.vertices) {
      report.notes.push(s.item.file + ': ' + s.vertices + ' vertices, the ground truth has ' + gt.vertices + ': no PMD_a');
      continue;
    }
    const frames = Math.min(s.frames, gt.frames);
    const perFrame = new Float64Array(frames);
    for (let k = 0; k < frames; ++k) perFrame[k] = distanceCm(s, gt, k, a, b);
    comparisons.push({ sequence: s, perFrame, mean: perFrame.reduce((x, y) => x + y, 0) / frames });
    report.pmdAFrames[s.item.label] = Array.from(perFrame);
  }
}

// === Drawing and controls

const frameTimes = [];

function draw() {
  const start = performance.now();
  const k = Math.max(0, currentFrame());
  for (const s of sequences) s.show(Math.min(k, s.frames - 1));
  renderer.render(scene, camera);
  const elapsed = performance.now() - start;
  frameTimes.push(elapsed);
  if (frameTimes.length > 60) frameTimes.shift();
  report.frameTimeMs = frameTimes.reduce((x, y) => x + y, 0) / frameTimes.length;
  report.renderedFrames += 1;
  report.frame = k;
  placeLabels(k);
  updateReadout(k);
}

function placeLabels(k) {
  const p = new THREE.Vector3();
  const w = view.clientWidth, h = view.clientHeight;
  report.pmdA = {};
  const gt = sequences.find((x) => x.item.role === 'ground_truth');
  const measure = gt && gt.mask ? 'PMD_a' : 'PMD';
  for (const s of sequences) {
    if (!s.label) continue;
    p.set((s.box.min.x + s.box.max.x) / 2, s.box.max.y + 0.04, (s.box.min.z + s.box.max.z) / 2).add(s.mesh.position);
    p.project(camera);
    s.label.style.left = ((p.x + 1) / 2 * w) + 'px';
    s.label.style.top = ((1 - p.y) / 2 * h) + 'px';
    const c = comparisons.find((x) => x.sequence === s);
    let text = s.item.label;
    if (c) {
      const value = c.perFrame[Math.min(k, c.perFrame.length - 1)];
      report.pmdA[s.item.label] = value;
      text += `<br><span class="pmd">${measure} ${value.toFixed(2)} cm (clip ${c.mean.toFixed(2)})</span>`;
    }
    s.label.innerHTML = text;
  }
}

function updateReadout(k) {
  const frames = clipFrames();
  slider.value = String(k);
  const ms = report.frameTimeMs ?? 0;
  readout.textContent = `frame ${k + 1} / ${frames} at ${clipFps()} fps · ${speed}x · draw ${ms.toFixed(1)} ms/frame`;
}

function step(delta) {
  playing = false;
  setPlayButton();
  const frames = clipFrames();
  const k = (currentFrame() + delta + frames) % Math.max(1, frames);
  clock = k / clipFps();
}
function setPlayButton() { document.getElementById('play').innerHTML = playing ? '&#10074;&#10074;' : '&#9654;'; }
document.getElementById('play').onclick = () => { playing = !playing; setPlayButton(); };
document.getElementById('back').onclick = () => step(-1);
document.getElementById('forward').onclick = () => step(1);
document.getElementById('speed').onchange = (event) => { speed = Number(event.target.value); };
slider.oninput = () => { playing = false; setPlayButton(); clock = Number(slider.value) / clipFps(); };
window.addEventListener('keydown', (event) => {
  if (event.target.tagName === 'SELECT' || event.target.tagName === 'INPUT') return;
  if (event.key === ' ') { playing = !playing; setPlayButton(); event.preventDefault(); }
  if (event.key === 'ArrowLeft') step(-1);
  if (event.key === 'ArrowRight') step(1);
});
setPlayButton();

let lastTime = null;
function tick(now) {
  requestAnimationFrame(tick);
  if (lastTime !== null && playing && sequences.length) {
    const duration = clipFrames() / clipFps();
    clock = (clock + speed * (now - lastTime) / 1000) % duration;
  }
  lastTime = now;
  controls.update();
  draw();
}

// === Start

async function start() {
  const name = params.get('manifest') ?? 'viewer.json';
  let response;
  try {
    response = await fetch(name);
  } catch (error) {
    fail(name + ': cannot fetch the manifest (' + error.message + ')');
    return;
  }
  if (!response.ok) { fail(name + ': cannot fetch the manifest (HTTP ' + response.status + ')'); return; }
  try {
    manifest = await response.json();
  } catch (error) {
    fail(name + ': expected JSON, found a parse error (' + error.message + ')');
    return;
  }
  if (manifest.format !== 'amt-viewer' || manifest.version !== 1) {
    fail(name + ': expected format "amt-viewer" version 1, found ' + JSON.stringify(manifest.format) + ' version ' +
         JSON.stringify(manifest.version));
    return;
  }
  if (!Array.isArray(manifest.groups) || manifest.groups.length === 0 ||
      manifest.groups.some((g) => !Array.isArray(g.items) || g.items.some((item) => typeof item.file !== 'string'))) {
    fail(name + ': groups: expected a list of groups, each with items {"file": ...}');
    return;
  }
  report.title = manifest.title ?? '';
  report.groups = manifest.groups.length;
  const select = document.getElementById('group');
  manifest.groups.forEach((g, k) => select.add(new Option(g.title ?? 'group ' + (k + 1), String(k))));
  select.hidden = manifest.groups.length < 2;
  select.onchange = () => loadGroup(Number(select.value));
  const first = Math.max(0, Math.min(manifest.groups.length - 1, Number(params.get('group')) || 0));
  select.value = String(first);
  requestAnimationFrame(tick);
  await loadGroup(first);
}
start();
