/* Find Me phone client: what every part of the page shares (ES module, no build step).
 *
 * The page's state (one WebSocket = one session: its photos, their hypotheses, selections,
 * scenes and measurements, the motions and poses, the limits the server announced), element
 * and number formatting (metres or feet and inches), the messages box, the busy indicator
 * and sending to the server. The parts of the page: settings.js (camera settings: lens,
 * height, gravity and the phone's motion sensors), capture.js (taking or picking a photo and
 * sending it), results.js (the photo with its boundary hypotheses and the taps on it),
 * points.js (the tapped points, what the user says they are on, and their 3D), motion.js (where you moved), plan.js (the room's floor plan) and app.js (the
 * connection, the server's messages and the wiring).
 */
export const $ = (id) => document.getElementById(id);
export const SVG = 'http://www.w3.org/2000/svg';
export const DEG = 180 / Math.PI;

export const state = {
  ws: null, session: null, services: [], seq: 0, measureSeq: 0,
  limits: {max_upload_bytes: 15 * 1024 * 1024, max_measure_pixels: 64, max_photos: 100},
  photos: [], current: -1, pending: new Map(), busy: new Map(), units: 'm',
  tapAs: null,   // what the user says the next taps are on: null (as the boundary says), 'floor', 'wall', 'top'
  motions: new Map(), poses: new Map(), trajectory: null, motionTimer: null,
  sensors: {on: false, samples: [], source: ''},
};

export function el(tag, attrs = {}, text) {
  const e = tag.startsWith('svg:') ? document.createElementNS(SVG, tag.slice(4))
                                   : document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) if (v !== undefined && v !== null) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}
export const mb = (n) => (n / 1e6).toFixed(1) + ' MB';
export function fmtLen(m, digits = 3) {
  if (m === null || m === undefined) return '–';
  if (state.units === 'm') return m.toFixed(digits) + ' m';
  const inches = Math.abs(m) / 0.0254, sign = m < 0 ? '−' : '';
  const ft = Math.floor(inches / 12);
  return `${sign}${ft} ft ${(inches - 12 * ft).toFixed(1)} in`;
}
export function fmtCoord(m) {
  return state.units === 'm' ? (m >= 0 ? '+' : '') + m.toFixed(2)
                             : (m >= 0 ? '+' : '') + (m / 0.3048).toFixed(2);
}
export function fmtSigma(m) {
  if (m === null || m === undefined) return '';
  return state.units === 'm' ? ` ± ${m.toFixed(3)} m` : ` ± ${(m / 0.0254).toFixed(1)} in`;
}

export function notify(text, kind = 'error', code = '') {
  const box = $('messages');
  const m = el('div', {class: `msg ${kind}`, role: kind === 'error' ? 'alert' : 'status',
                       'data-code': code});
  m.append(el('span', {class: 'msg-text'}, text));
  const x = el('button', {type: 'button', class: 'msg-close', 'aria-label': 'dismiss'}, '×');
  x.addEventListener('click', () => m.remove());
  m.append(x);
  box.prepend(m);
  while (box.children.length > 3) box.lastElementChild.remove();
  if (kind !== 'error') setTimeout(() => m.remove(), 8000);
  return m;
}
export const ERROR_HINTS = {
  TOO_LARGE: 'Try a smaller photo.', BAD_IMAGE: 'Send a JPEG, PNG or WebP photo.',
  BAD_CAMERA: 'Check the camera settings.', OVERLOADED: 'Try again in a moment.',
};

export function setBusy(key, text) { state.busy.set(key, text); renderBusy(); }
export function clearBusy(key) { state.busy.delete(key); renderBusy(); }
export function renderBusy() {
  const b = $('busy');
  const texts = [...state.busy.values()];
  b.hidden = texts.length === 0;
  $('busy-text').textContent = texts[texts.length - 1] || '';
  document.body.setAttribute('aria-busy', texts.length ? 'true' : 'false');
  document.body.dataset.busy = texts.length ? [...state.busy.keys()].join(' ') : '';
}
export const photoAt = (n) => state.photos.find((p) => p.index === n);
// the colour of hypothesis `rank` (1-based): its line on the photo, its chip, its pick button
const COLORS = ['#e6194b', '#3cb44b', '#4363d8', '#f58231', '#911eb4', '#00a5b8',
                '#f032e6', '#7a9c00', '#9a6324', '#469990'];
export const hypColor = (rank) => COLORS[(rank - 1) % COLORS.length];
export function hypSwatch(rank) {   // a dot of hypothesis `rank`'s colour, for its buttons
  const sw = el('span', {class: 'swatch'});
  sw.style.background = hypColor(rank);
  return sw;
}
export function setStatus(s, text) {
  const e = $('status');
  e.dataset.state = s;
  e.textContent = text;
}
export function send(obj) {
  if (!state.ws || state.ws.readyState !== WebSocket.OPEN) {
    notify('Not connected to the server. Start a new session.', 'error', 'CLOSED');
    return false;
  }
  state.ws.send(typeof obj === 'string' || obj instanceof ArrayBuffer ? obj : JSON.stringify(obj));
  return true;
}
