// Everything the page knows, in one object: the modules read and write these fields and keep no
// other state of their own that another module needs. Tests read it through the facade
// (facade.js), never directly.

/**
 * A space as drawn: its decoded mesh (protocol.js `decodeMesh`) and what the page keeps for it.
 * @typedef {object} Space
 * @property {number} space index in the hello's `spaces`
 * @property {number} vertices corner vertices drawn
 * @property {Float32Array} rest rest positions, 3 per vertex (m, part frame)
 * @property {Uint32Array} triangles surface triangles, 3 vertex indices each
 * @property {Uint8Array} fixed per vertex, bit c set when component c is held
 * @property {Uint32Array|null} faces each triangle's CAD face tag, when the basis has them
 * @property {any} geom the surface's THREE.BufferGeometry (drawn positions and colours)
 * @property {any} mesh its THREE.Mesh
 * @property {any} edges the mesh's edges over it (a wireframe child of `mesh` on the same geometry)
 * @property {any} box the volume of interest's THREE.Box3Helper, or null
 * @property {any} supports the held vertices' THREE.Points, or null
 * @property {number[]} fixedIdx the held vertices
 * @property {number} size bounding-box diagonal at rest (m)
 * @property {Float32Array} u the latest frame's elastic displacement (m, part frame)
 * @property {Float32Array} umag |u| per vertex
 * @property {Float32Array} truePos where each vertex is, unmagnified (where hands act)
 * @property {number[]|null} pose the latest frame's pose (x, y, z, w, qx, qy, qz), null when held
 * @property {number[]|null} drawnPose the pose the drawing used
 * @property {Float32Array|null} vm von Mises stress per vertex, while colouring by stress
 * @property {Float32Array|null} p1 largest principal stress per vertex, likewise
 * @property {boolean} [alarm] the latest frame's alarm
 * @property {{vertex: number, vonMises: number}} [peak] the latest frame's largest von Mises
 * @property {number} [frameTime] the latest frame's session time (s)
 */

/** How many redraw times the drawn rate is measured over. */
export const DRAW_WINDOW = 60;

export const state = {
  // The connection.
  /** The WebSocket is open. */
  connected: false,
  /** Hellos after the first (a reconnect or a new basis). */
  reconnects: 0,
  /** The server's hello (null before the first). @type {any} */
  hello: null,
  /** Why the page stopped listening to the server (another protocol version), or null. @type {string|null} */
  refused: null,
  /** The latest status (rates, hands, clients). @type {any} */
  status: null,
  /** The set-up panel's notes (progress, computed, checked, compute_error), the last 200. @type {any[]} */
  notes: [],
  /** ms from a pointer event to the first frame computed after the server got it, the last 500. @type {number[]} */
  latency: [],
  /** The last hand target sent (m, part frame). @type {number[]|null} */
  lastTarget: null,

  // Readiness.
  /** Every space's mesh is in and a frame has been drawn. */
  ready: false,
  /** Every space's mesh is in. */
  meshesIn: false,
  /** The frame count at the last hello. */
  framesAtHello: 0,
  /** The hello is of the part already shown (a reconnect): the view stays. */
  keepView: false,

  // The part.
  /** Each space as drawn, by index. @type {Space[]} */
  spaces: [],
  /** The space shown. */
  active: 0,
  /** Space 0's bounding-box diagonal (m). @type {number|undefined} */
  diag: undefined,

  // Frames.
  /** Frames received. */
  frames: 0,
  /** Frames the server numbered that never came. */
  framesSkipped: 0,
  /** The last frame's number. */
  lastSeq: -1,
  /** Something on screen changed: the part is redrawn at the next animation frame. */
  dirty: false,
  /** Times of the last DRAW_WINDOW redraws (ms), a ring. */
  drawTimes: new Float64Array(DRAW_WINDOW),
  /** Redraws since the page opened (drawTimes' write position). */
  draws: 0,
  /** Redraws per second over drawTimes. */
  framesPerSecond: 0,
  /** Renders of the scene. */
  renders: 0,

  // How the part is drawn.
  /** The deformation scale typed in. */
  scale: 1,
  /** The deformation scale is automatic. */
  scaleAuto: true,
  /** The automatic scale at rest. */
  autoScale: 1,
  /** The scale the last drawing used. @type {number|undefined} */
  drawnScale: undefined,
  /** The largest |u| since the part was last at rest (0 at rest). */
  episodePeak: 0,
  /** Each colouring's range since the part was last at rest. @type {Record<string, {lo: number, hi: number}>} */
  episodes: {},
  /** What the part is coloured by: displacement, vonmises, principal, safety. */
  colour: 'displacement',
  /** Units shown: 'si' or 'mm'. */
  units: 'si',
  /** A locked colour range, or null. @type {{colour: string, lo: number, hi: number}|null} */
  locked: null,
  /** The field last coloured (field.js), for the probe. @type {any} */
  field: null,
  /** The legend last drawn (also for pictures). @type {any} */
  legend: null,

  // What is shown instead of the live part.
  /** The mode shape animated, or null. @type {any} */
  mode: null,
  /** The static load case shown, or null. @type {any} */
  loadCase: null,
  /** The load case asked for, until it comes. @type {{space: number, index: number}|null} */
  loadWanted: null,

  // Under the cursor.
  /** The probe: the vertex under the cursor and where, or null. @type {{vertex: number, x: number, y: number, text?: string}|null} */
  probe: null,
  /** Probes pinned by a double-click: a vertex of a space each (and its rest position, to find
   * it again on a recomputed mesh of the same part), numbered P1, P2, … in the order pinned;
   * their values follow the part (a pull, a load case); `extremes`: per colouring, the extreme
   * over the last motion (hud.js).
   * @type {{space: number, vertex: number, rest: number[], n: number, extremes: Record<string, number>, moving: boolean}[]} */
  pins: [],
  /** The CAD face under the cursor while faces are picked, or null. @type {number|null} */
  hoverFace: null,
};
