// The test facade, `window.ves`: what the browser tests (pipeline/tests/view/*.mjs) and the
// benchmark (bench/view.mjs) read and call, and nothing else. Values are read live from the
// page's state; the functions answer in the page's own terms (vertices, metres, CSS pixels).
// A test that needs more adds it here, named for what it asks.
import * as THREE from 'three';
import { kindOf } from './protocol.js';
import { setScale } from './scale.js';
import { state } from './state.js';
import { drive, release } from './interaction.js';
import { nearestVertex } from './spaces.js';
import { camera, canvas, screenOfPoint } from './viewport.js';

const v = new THREE.Vector3();

/** The facade over `state` and the set-up panel (`setup`: its `scene()`). */
export function facade(setup) {
  return Object.freeze({
    // The connection and what came over it.
    get connected() { return state.connected; },
    get reconnects() { return state.reconnects; },
    get hello() { return state.hello; },
    get status() { return state.status; },
    get notes() { return state.notes; },
    get frames() { return state.frames; },
    get latency() { return state.latency; },
    get lastTarget() { return state.lastTarget; },
    /** The kind of a binary message (protocol.js), for a test's own WebSocket. */
    kindOf,
    // What is drawn.
    get ready() { return state.ready; },
    get dirty() { return state.dirty; },
    get renders() { return state.renders; },
    get framesPerSecond() { return state.framesPerSecond; },
    /** Each space: rest, u, umag, pose, drawnPose, vm, vertices, size (see state.js's Space). */
    get spaces() { return state.spaces; },
    get diag() { return state.diag; },
    get legend() { return state.legend; },
    get drawnScale() { return state.drawnScale; },
    get scaleAuto() { return state.scaleAuto; },
    get mode() { return state.mode; },
    get loadCase() { return state.loadCase; },
    get hoverFace() { return state.hoverFace; },
    /** Where vertex `vertex` of space `space` is drawn on the screen (CSS px). */
    screenOf(space, vertex) {
      camera.updateMatrixWorld();
      return screenOfPoint(v.fromBufferAttribute(state.spaces[space].geom.attributes.position, vertex));
    },
    /** Its true position (m, part frame: unmagnified). */
    trueOf: (space, vertex) => Array.from(state.spaces[space].truePos.subarray(3 * vertex, 3 * vertex + 3)),
    /** Its drawn position (m: magnified by the deformation scale). */
    drawnOf: (space, vertex) => Array.from(state.spaces[space].geom.attributes.position.array.subarray(3 * vertex, 3 * vertex + 3)),
    /** Every drawn position of space `space` (3 per vertex, m), a copy. */
    drawnPositions: (space) => Float32Array.from(state.spaces[space].geom.attributes.position.array),
    /** The vertex nearest `p` at rest (m, part frame). */
    nearestVertex(space, p) {
      const s = state.spaces[space];
      return nearestVertex(s.rest, s.vertices, p);
    },
    /** The pinned probes of the active space as drawn: number, vertex, the field's value there
     * and the label shown. */
    get pins() {
      return state.pins.filter((p) => p.space === state.active && p.vertex >= 0).map((p) => ({
        n: p.n, vertex: p.vertex, value: state.field ? state.field.valueAt(p.vertex) : null,
        text: [...document.querySelectorAll('.pin')].map((t) => t.textContent).find((t) => t.startsWith(`P${p.n} `)) || null,
      }));
    },
    /** Whether the active space is drawn with its mesh's edges over it. */
    edgesShown() {
      const s = state.spaces[state.active];
      return Boolean(s && s.mesh.visible && s.edges.visible && s.edges.parent === s.mesh);
    },
    /** Screen rectangle (CSS px) of every drawn vertex of the active space: [xmin, ymin, xmax, ymax]. */
    drawnExtent() {
      const s = state.spaces[state.active];
      camera.updateMatrixWorld();
      const r = canvas.getBoundingClientRect();
      let box = [Infinity, Infinity, -Infinity, -Infinity];
      for (let i = 0; i < s.vertices; i++) {
        v.fromBufferAttribute(s.geom.attributes.position, i).project(camera);
        const x = r.left + ((v.x + 1) / 2) * r.width, y = r.top + ((1 - v.y) / 2) * r.height;
        box = [Math.min(box[0], x), Math.min(box[1], y), Math.max(box[2], x), Math.max(box[3], y)];
      }
      return box;
    },
    // Acting as the user.
    /** Grabs with hand `hand` at `position` (m, part frame) or moves it there. */
    drive,
    /** Lets go of hand `hand`. */
    release,
    /** A fixed deformation scale, or 'auto'. */
    setScale,
    /** The set-up panel: `scene()`, the scene as edited. */
    setup: Object.freeze({ scene: () => setup.scene(), state: () => setup.last() }),
  });
}
