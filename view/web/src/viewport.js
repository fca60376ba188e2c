// The 3-D view: renderer, scene, camera (with its light), orbit controls; screen coordinates;
// the views that find the part again (home, fit, along an axis); rendering only when something
// may have changed on screen.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import * as views from './camera.js';
import { $ } from './dom.js';
import { state } from './state.js';

/** The canvas drawn into. @type {HTMLCanvasElement} */
export const canvas = $('view');
export const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
export const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2126);
export const camera = new THREE.PerspectiveCamera(35, 1, 1e-4, 1e4);
camera.up.set(0, 0, 1);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404850, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
// Lit from over the viewer's shoulder whatever the view: the light rides with the camera.
const sunTarget = new THREE.Object3D();
sunTarget.position.set(0, 0, -1);
sun.position.set(0.5, 1, 0.2);
sun.target = sunTarget;
camera.add(sun, sunTarget);
scene.add(camera);
export const controls = new OrbitControls(camera, canvas);
controls.enableDamping = false;

const projected = new THREE.Vector3();

/** Where point `p` (a THREE.Vector3) is drawn on the screen, CSS px, into `out` ([x, y]). */
export function screenOfPoint(p, out = [0, 0]) {
  projected.copy(p).project(camera);
  const r = canvas.getBoundingClientRect();
  out[0] = r.left + ((projected.x + 1) / 2) * r.width;
  out[1] = r.top + ((1 - projected.y) / 2) * r.height;
  return out;
}

/** A pointer event's position in normalised device coordinates, into `out` (a THREE.Vector2). */
export function ndc(ev, out = new THREE.Vector2()) {
  const r = canvas.getBoundingClientRect();
  return out.set(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
}

/** Fits what is drawn now (deformed, posed) looking along `direction` (default: as now). */
export function fitView(direction) {
  const s = state.spaces[state.active];
  if (!s) return;
  s.geom.computeBoundingSphere();
  const dir = direction || camera.getWorldDirection(new THREE.Vector3());
  views.fit(camera, controls, s.geom.boundingSphere, dir);
}

/** The first view. */
export function homeView() { fitView(views.HOME); }

/** Looking from the +axis side (sign 1) or the −axis side (−1). */
export function viewAlong(axis, sign) { fitView(views.along(axis, sign)); }

function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

// The scene is rendered when something may have changed on screen: the part redrawn, a mode
// animated, the user's input in the last second (camera, picks, hover, panels), a recording; and
// at least every RENDER_IDLE_MS whatever happens. A part at rest then costs the browser (and,
// without a GPU, the cores a compute beside it needs) almost nothing.
const RENDER_IDLE_MS = 1000;
let lastInput = 0, lastRender = 0;
const woken = () => { lastInput = performance.now(); };
for (const ev of ['pointermove', 'pointerdown', 'pointerup', 'wheel', 'keydown', 'keyup', 'resize', 'change', 'input', 'click']) {
  window.addEventListener(ev, woken, { passive: true, capture: true });
}
controls.addEventListener('change', woken);

/** Renders the scene if `drew` or if it may have changed otherwise (`busy`: a recording);
 * returns whether it did. */
export function renderIfNeeded(drew, busy) {
  controls.update();
  const now = performance.now();
  if (!(drew || now - lastInput < 1000 || now - lastRender >= RENDER_IDLE_MS || busy)) return false;
  renderer.render(scene, camera);
  lastRender = now;
  state.renders += 1;
  return true;
}
