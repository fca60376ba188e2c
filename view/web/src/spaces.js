// The scene graph of the part: one mesh per space (the global one and each volume of interest's),
// its box, its supports as points, the CAD faces lit while the supports are picked; and what
// each frame and stress message changes in it. Whatever is replaced is disposed: a new basis
// (a compute, a reconnect) frees the old one's GPU memory.
import * as THREE from 'three';
import { $ } from './dom.js';
import { autoScale } from './scale.js';
import { state } from './state.js';
import { homeView, scene } from './viewport.js';

/** Colours of lit faces: the one under the cursor, the ones held, the ones loaded. */
export const HOVER = 0xffd45e, HELD = 0x3ddc84, LOADED = 0xff7a45;

/** Removes every space from the scene and frees their geometries and materials. */
export function clearSpaces() {
  for (const kind of Object.keys(faceLights)) lightFaces(kind, [], 0);
  for (const s of state.spaces) {
    if (!s) continue;
    scene.remove(s.mesh);
    s.geom.dispose();
    s.mesh.material.dispose();
    s.edges.material.dispose();
    if (s.box) { scene.remove(s.box); s.box.dispose(); }
    if (s.supports) { scene.remove(s.supports); s.supports.geometry.dispose(); s.supports.material.dispose(); }
  }
  state.spaces = [];
  state.mode = null;
}

/** The vertex of `rest` (3 per vertex, `n` vertices) nearest point `p`. */
export function nearestVertex(rest, n, p) {
  let best = -1, bd = Infinity;
  for (let i = 0; i < n; i++) {
    const d = (rest[3 * i] - p[0]) ** 2 + (rest[3 * i + 1] - p[1]) ** 2 + (rest[3 * i + 2] - p[2]) ** 2;
    if (d < bd) { bd = d; best = i; }
  }
  return best;
}

/** Adds the decoded mesh `m` (protocol.js) as a space; `lit`: the CAD faces held and the ones
 * loaded, lit on space 0. @param {any} m @param {{ held: number[], loaded: number[] }} lit */
export function addSpace(m, lit) {
  const geom = new THREE.BufferGeometry();
  geom.setAttribute('position', new THREE.BufferAttribute(new Float32Array(m.rest), 3).setUsage(THREE.DynamicDrawUsage));
  const col = new Float32Array(3 * m.vertices).fill(0.8);
  geom.setAttribute('color', new THREE.BufferAttribute(col, 3).setUsage(THREE.DynamicDrawUsage));
  geom.setIndex(new THREE.BufferAttribute(m.triangles, 1));
  geom.computeBoundingBox();
  // Flat shading: an FE surface has sharp edges that averaged normals would smear.
  const mat = new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.6, metalness: 0.1, side: THREE.DoubleSide, flatShading: true });
  // Pushed back a little so that the mesh's edges, drawn on the same triangles, stay in front.
  mat.polygonOffset = true; mat.polygonOffsetFactor = 1; mat.polygonOffsetUnits = 1;
  const mesh = new THREE.Mesh(geom, mat);
  mesh.visible = m.space === state.active;
  // The surface mesh's edges ("mesh edges" in Show): the same geometry, so they deform with the
  // part; a child, so they are shown with it and move with a free body's pose.
  const edges = new THREE.Mesh(geom, new THREE.MeshBasicMaterial({ color: 0x10161c, wireframe: true, transparent: true, opacity: 0.45 }));
  edges.visible = $('showedges').checked;
  mesh.add(edges);
  scene.add(mesh);
  const info = state.hello.spaces[m.space];
  let box = null;
  if (info.voi) {
    box = new THREE.Box3Helper(new THREE.Box3(new THREE.Vector3(...info.voi[0]), new THREE.Vector3(...info.voi[1])), 0x5a7a8c);
    scene.add(box);
  }
  // Supports: the vertices with a fixed component, as green points over the part.
  const fixedIdx = [];
  m.fixed.forEach((b, i) => { if (b) fixedIdx.push(i); });
  let supports = null;
  if (fixedIdx.length) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * fixedIdx.length), 3));
    supports = new THREE.Points(g, new THREE.PointsMaterial({ color: HELD, size: 4, sizeAttenuation: false, depthTest: true }));
    supports.visible = mesh.visible && $('showsupports').checked;
    scene.add(supports);
  }
  const size = geom.boundingBox.getSize(new THREE.Vector3()).length();
  state.spaces[m.space] = {
    ...m, geom, mesh, edges, box, supports, fixedIdx, size,
    u: new Float32Array(3 * m.vertices), umag: new Float32Array(m.vertices),
    truePos: new Float32Array(m.rest), pose: null, drawnPose: null, vm: null, p1: null,
  };
  // The pins of this space on its new mesh: the vertex nearest where each was pinned.
  for (const p of state.pins) if (p.space === m.space) p.vertex = nearestVertex(m.rest, m.vertices, p.rest);
  if (m.space === 0) {
    // The same part again (a reconnect): the user's view stays; another part is framed.
    const same = state.keepView && state.diag && Math.abs(size - state.diag) <= 1e-6 * size;
    state.diag = size;
    state.autoScale = autoScale();
    if (!same) homeView();
  }
  highlightBoxes();
  if (m.space === 0) lightSetup(lit);
  // Ready once every space is in and a frame has been drawn (see main.js's loop).
  if (state.spaces.filter(Boolean).length === state.hello.spaces.length) state.meshesIn = true;
}

/** The active space's box yellow, the others grey. */
function highlightBoxes() {
  state.spaces.forEach((s, i) => {
    if (!s || !s.box) return;
    const on = i === state.active;
    s.box.material.color.set(on ? 0xffd45e : 0x5a7a8c);
    s.box.material.opacity = on ? 1 : 0.5;
    s.box.material.transparent = !on;
  });
}

/** Draws the mesh's edges on every space (or not), as the checkbox says. */
export function showEdges() {
  for (const s of state.spaces) if (s) s.edges.visible = $('showedges').checked;
}

/** Shows the supports (or not, as the checkbox says) of the spaces shown. */
export function showSupports() {
  for (const s of state.spaces) if (s && s.supports) s.supports.visible = s.mesh.visible && $('showsupports').checked;
}

/** The supports' points where `positions` (3 per vertex) draws their vertices. */
export function supportsFollow(s, positions) {
  if (!s.supports) return;
  const p = s.supports.geometry.attributes.position.array;
  for (let j = 0; j < s.fixedIdx.length; j++) {
    const v = s.fixedIdx[j];
    p[3 * j] = positions[3 * v]; p[3 * j + 1] = positions[3 * v + 1]; p[3 * j + 2] = positions[3 * v + 2];
  }
  s.supports.geometry.attributes.position.needsUpdate = true;
  s.supports.geometry.computeBoundingSphere();
}

/** A decoded frame (protocol.js) of a space that is in: kept for the next drawing. Returns
 * whether the active space changed. */
export function onFrame(f) {
  const s = state.spaces[f.space];
  if (state.lastSeq >= 0 && f.seq > state.lastSeq + 1) state.framesSkipped += f.seq - state.lastSeq - 1;
  state.lastSeq = f.seq;
  state.frames += 1;
  // Frames keep coming at rest: one that moves no drawn point by a millionth of the part (nor
  // the pose, the alarm or the peak) is not redrawn, so a part at rest costs the page nothing.
  const switched = f.space !== state.active;
  let change = 0;
  for (let i = 0; i < f.u.length; i++) change = Math.max(change, Math.abs(f.u[i] - s.u[i]));
  const still = !switched && change * (state.drawnScale || 0) <= 1e-6 * (state.diag || 0)
    && samePose(s.pose, f.pose)
    && s.alarm === f.alarm && s.peak && s.peak.vertex === f.peakVertex && s.peak.vonMises === f.peakVonMises;
  if (switched) {
    for (const t of state.spaces) if (t) { t.mesh.visible = false; if (t.supports) t.supports.visible = false; }
    state.active = f.space;
    highlightBoxes();
  }
  s.mesh.visible = true;
  if (s.supports) s.supports.visible = $('showsupports').checked;
  s.u.set(f.u);
  for (let i = 0; i < s.vertices; i++) s.umag[i] = Math.hypot(f.u[3 * i], f.u[3 * i + 1], f.u[3 * i + 2]);
  s.pose = f.pose;
  s.alarm = f.alarm;
  if (!s.peak) s.peak = { vertex: -1, vonMises: NaN };
  s.peak.vertex = f.peakVertex;
  s.peak.vonMises = f.peakVonMises;
  s.frameTime = f.time;
  // A load case shown stays as it is: the live frames are kept for when it is put away.
  if (!still && !state.loadCase) state.dirty = true;
  return switched;
}

// Poses as frames carry them: null for a held part.
function samePose(a, b) {
  if (!a || !b) return true;
  for (let i = 0; i < a.length; i++) if (a[i] !== b[i]) return false;
  return true;
}

/** A decoded stress message: the fields of its space, coloured at the next drawing. */
export function onStress(m) {
  const s = state.spaces[m.space];
  // The stress of a frame before a swap (another part's vertex count) is not this part's.
  if (!s || m.vonMises.length !== s.vertices) return;
  s.vm = m.vonMises;
  s.p1 = m.principal;
  state.dirty = true;
}

// Faces: each CAD face's triangles, lit when the cursor is over it (yellow) or held (green). The
// overlay shares the part's drawn positions: it follows the drawing.
const faceLights = { hover: null, held: null, loaded: null };
function faceOverlay(s, tags, colour) {
  const want = new Set(tags);
  const idx = [];
  for (let t = 0; t < s.faces.length; t++) if (want.has(s.faces[t])) idx.push(s.triangles[3 * t], s.triangles[3 * t + 1], s.triangles[3 * t + 2]);
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', s.geom.attributes.position);
  g.setIndex(idx);
  const m = new THREE.Mesh(g, new THREE.MeshBasicMaterial({ color: colour, transparent: true, opacity: 0.55, side: THREE.DoubleSide,
    polygonOffset: true, polygonOffsetFactor: -2, polygonOffsetUnits: -2, depthWrite: false }));
  m.renderOrder = 1;
  return m;
}

/** Lights the faces the set-up names on space 0: the held ones green, the loaded ones orange.
 * @param {{ held: number[], loaded: number[] }} lit */
export function lightSetup(lit) {
  lightFaces('held', lit.held, HELD);
  lightFaces('loaded', lit.loaded, LOADED);
}

/** Lights the CAD faces `tags` of space 0 as `kind` ('hover', 'held' or 'loaded') in `colour`;
 * none: off. */
export function lightFaces(kind, tags, colour) {
  const s = state.spaces[0];
  const old = faceLights[kind];
  if (old) {
    scene.remove(old);
    // The position attribute is the part's: taken out first, so disposing frees only the
    // overlay's own index buffer.
    old.geometry.deleteAttribute('position');
    old.geometry.dispose();
    old.material.dispose();
    faceLights[kind] = null;
  }
  if (!s || !s.faces || !tags.length) return;
  faceLights[kind] = faceOverlay(s, tags, colour);
  scene.add(faceLights[kind]);
}
