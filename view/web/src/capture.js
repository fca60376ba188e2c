// Pictures for reports: a PNG of the view with its legend and a short WebM recording
// (the browser's MediaRecorder), both drawn from one composite of the canvas and the legend.
import { gradient } from './colours.js';

const composite = document.createElement('canvas');

/** Draws the 3-D view, the labels over it (`extra.labels`: {text, x, y, colour} in CSS px),
 * the readout lines (`extra.lines`, top left) and the legend (`legend`: {title, scale, ticks,
 * caption}) into one canvas. */
export function draw(view, legend, extra = { labels: [], lines: [] }) {
  composite.width = view.width; composite.height = view.height;
  const g = composite.getContext('2d');
  g.drawImage(view, 0, 0);
  const k = view.width / Math.max(1, view.clientWidth);
  g.font = `600 ${13 * k}px system-ui, sans-serif`;
  g.shadowColor = '#000'; g.shadowBlur = 3 * k;
  for (const l of extra.labels) { g.fillStyle = l.colour || '#fff'; g.fillText(l.text, l.x * k, (l.y + 12) * k); }
  const lines = extra.lines.filter((t) => t);
  lines.forEach((t, i) => { g.fillStyle = i === lines.length - 1 && extra.warn ? '#ff7b6b' : '#e8e8e8'; g.fillText(t, 12 * k, (22 + 17 * i) * k, view.width - 24 * k); });
  g.shadowBlur = 0;
  const w = 300 * k, pad = 10 * k, x = pad, h = 78 * k, y = view.height - h - pad;
  g.fillStyle = 'rgba(20,24,28,0.85)';
  g.fillRect(x, y, w + 2 * pad, h);
  g.fillStyle = '#e8e8e8';
  g.font = `${13 * k}px system-ui, sans-serif`;
  g.fillText(legend.title, x + pad, y + 18 * k, w);
  const bar = legend.scale === 'neutral' ? [['#b8bcc2', 0], ['#b8bcc2', 1]] : stops(gradient(legend.scale));
  const grad = g.createLinearGradient(x + pad, 0, x + pad + w, 0);
  for (const [c, at] of bar) grad.addColorStop(at, c);
  g.fillStyle = grad;
  g.fillRect(x + pad, y + 26 * k, w, 12 * k);
  g.fillStyle = '#e8e8e8';
  const [lo, mid, hi] = legend.ticks;
  g.textAlign = 'left'; g.fillText(lo, x + pad, y + 54 * k);
  g.textAlign = 'center'; g.fillText(mid, x + pad + w / 2, y + 54 * k);
  g.textAlign = 'right'; g.fillText(hi, x + pad + w, y + 54 * k);
  g.textAlign = 'left';
  g.fillStyle = '#b8c0c8';
  g.fillText(legend.caption, x + pad, y + 71 * k, w);
  return composite;
}

// "linear-gradient(to right, rgb(..) 0%, rgb(..), …)" -> [[colour, offset 0..1]].
function stops(css) {
  const parts = css.replace(/^linear-gradient\(to right,\s*/, '').replace(/\)$/, '').split(/,\s*(?=rgb)/);
  return parts.map((p, i) => {
    const m = p.match(/(rgb\([^)]*\))\s*([\d.]+)?%?/);
    return [m[1], m[2] !== undefined ? Number(m[2]) / 100 : i / (parts.length - 1)];
  });
}

/** Saves `blob` as a download named `name`. */
export function download(blob, name) {
  const a = document.createElement('a');
  a.href = URL.createObjectURL(blob);
  a.download = name;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);
}

const stamp = () => new Date().toISOString().replace(/[:.]/g, '-').slice(0, 19);

/** Saves the composite as a PNG named after the part. */
export function screenshot(view, legend, name, extra) {
  draw(view, legend, extra).toBlob((b) => b && download(b, `${name}-${stamp()}.png`), 'image/png');
}

let recorder = null;
/** Starts or stops a WebM recording of the composite; true while recording. */
export function toggleRecording(view, legend, name, extra) {
  if (recorder) { recorder.stop(); recorder = null; return false; }
  if (typeof MediaRecorder === 'undefined') throw new Error('this browser cannot record video (no MediaRecorder)');
  draw(view, legend, extra);
  const chunks = [];
  const type = ['video/webm;codecs=vp9', 'video/webm'].find((t) => MediaRecorder.isTypeSupported(t)) || '';
  recorder = new MediaRecorder(composite.captureStream(30), type ? { mimeType: type } : {});
  recorder.ondataavailable = (e) => { if (e.data.size) chunks.push(e.data); };
  recorder.onstop = () => download(new Blob(chunks, { type: 'video/webm' }), `${name}-${stamp()}.webm`);
  recorder.start(500);
  return true;
}

/** While recording, each drawn frame goes to the composite. */
export function recording() { return recorder !== null; }
