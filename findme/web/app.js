/* Find Me phone client: capture a photo, pick the floor boundary, tap points, see motion.
 * This module (loaded last, an ES module like the parts it imports) holds the connection,
 * the server's messages and the wiring; common.js says what each part of the page does.
 *
 * Talks to the gateway (services/gateway.py) over one WebSocket = one session:
 *   binary  [u32 big-endian n][n bytes JSON header][photo bytes]   a photo
 *   text    {"type": "select", index, rank, camera_height_m}         another hypothesis
 *   text    {"type": "measure", id, index, pixels: [[u, v], ...],    3D of tapped pixels
 *            surfaces: [null | "floor" | "wall", ...]}               (optional) one per pixel:
 *                                                                    what the user says it is on
 * and gets JSON: hello, frame, refused, hypotheses, selection, scene, measure (each point
 * with what was said of it: said), motion, pose, trajectory, plan (drawn by plan.js), error.
 * Pixels follow the bus convention: (0, 0) is the centre of the top-left pixel.
 */
import {$, clearBusy, notify, photoAt, renderBusy, send, setBusy, setStatus, state,
        ERROR_HINTS} from './common.js';
import {initCapture} from './capture.js';
import {expectMotion, renderMotion} from './motion.js';
import {measure} from './points.js';
import {initResults, render, show} from './results.js';
import {autoRotation, cameraHeading, currentGravity, currentHeading, currentHeadingFields,
        deviceGravityFromMotion,
        deviceGravityFromOrientation, deviceToCamera, initSettings, rotation} from './settings.js';

// ------------------------------------------------------------------ connection
function connect() {
  const proto = location.protocol === 'https:' ? 'wss' : 'ws';
  const ws = new WebSocket(`${proto}://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  state.ws = ws;
  setStatus('connecting', 'connecting…');
  ws.onmessage = (ev) => {
    let msg;
    try { msg = JSON.parse(ev.data); } catch (e) { return; }
    handle(msg);
  };
  ws.onclose = (ev) => {
    setStatus('closed', 'disconnected');
    state.busy.clear(); renderBusy();
    const why = ev.code === 1009 ? 'the last message was too large for the server'
              : ev.code === 1013 ? 'the server is busy'
              : ev.reason || `code ${ev.code}`;
    notify(`Connection to the server closed (${why}). Start a new session to go on.`,
           'error', 'CLOSED');
    $('new-session-btn').hidden = false;
  };
}

// ------------------------------------------------------------------ server messages
function handle(msg) {   // one server message (JSON) -> the page's state and view
  const f = HANDLERS[msg.type];
  if (f) f(msg);
}
const HANDLERS = {
  hello(m) {
    state.session = m.session;
    state.services = m.services || [];
    Object.assign(state.limits, m.limits || {});
    $('session').textContent = m.session;
    setStatus('connected', 'connected');
  },
  pong() {},
  frame(m) {
    const pend = state.pending.get(m.id);
    state.pending.delete(m.id);
    const p = {index: m.index, url: pend ? pend.url : '', name: pend ? pend.name : '',
               width: m.width, height: m.height, hyps: null, reason: '', rank: 0, by: '',
               sceneRank: 0, metric: false, height_m: m.camera_height_m, points: [],
               surfaces: [], reply: null, measureId: 0, camera: null,
               sentGravity: pend ? pend.gravity : null,
               gravitySent: pend ? pend.gravitySource : null, serverGravity: m.gravity};
    state.photos.push(p);
    setBusy('upload', 'Finding the floor boundary…');
    show(p.index);
    $('settings').open = false;
    $('result').scrollIntoView({block: 'start'});
    if (m.reencoded) notify('The photo was turned upright (its EXIF rotation) before measuring.', 'info');
  },
  refused(m) {
    const pend = state.pending.get(m.id);
    if (pend) { URL.revokeObjectURL(pend.url); state.pending.delete(m.id); }
    clearBusy('upload');
  },
  hypotheses(m) {
    const p = photoAt(m.index);
    if (!p) return;
    p.hyps = m.hypotheses;
    p.reason = m.reason;
    p.notRoom = m.not_room_view || '';
    p.camera = m.camera || null;
    clearBusy('upload');
    if (p.camera && p.camera.gravity_source === 'level') {
      notify(`Photo ${m.index + 1}: the photo does not show which way is down, so the camera ` +
             'is taken as level and distances may be far off. Use the live camera with the ' +
             'motion sensors on, or type the phone\'s tilt.', 'warn', 'LEVEL');
    }
    if (!m.hypotheses.length) {
      notify(`No floor boundary found in photo ${m.index + 1}: ${m.reason}`, 'warn', 'NO_HYPOTHESES');
    } else {
      if (p.notRoom) {
        notify(`Photo ${m.index + 1} does not look like a room: ${p.notRoom}. Its boundaries ` +
               'below are guesses.', 'warn', 'NOT_ROOM_VIEW');
      }
      setBusy('scene', 'Building the 3D scene…');
    }
    if (p.index === state.current) render();
  },
  selection(m) {
    const p = photoAt(m.index);
    if (!p) return;
    p.rank = m.rank;
    p.by = m.by;
    // the scene of this selection may already be here (the bus does not order the
    // selection, published by the gateway, against the scene, published by measurement)
    const sceneHere = p.sceneRank === m.rank &&
      (m.camera_height_m === null || m.camera_height_m === p.height_m);
    if (sceneHere) clearBusy('scene'); else setBusy('scene', 'Building the 3D scene…');
    if (p.index === state.current) render();
  },
  scene(m) {
    const p = photoAt(m.index);
    if (!p) return;
    p.sceneRank = m.rank;
    p.metric = m.metric;
    p.height_m = m.camera_height_m;
    p.gravity = m.gravity;       // down, in the camera's frame: a point's height is h - g . xyz
    p.walls = m.walls_m || [];   // its boundary's walls on the floor, its level frame
    if (m.rank === p.rank) clearBusy('scene');
    if (state.poses.size || state.motions.size) renderMotion();
    if (p.points.length) measure(p);
    if (p.index === state.current) render();
    if (m.index > 0) expectMotion(m.index);
  },
  measure(m) {
    const p = photoAt(m.index);
    if (p && m.id === p.measureId) {
      clearBusy('measure');
      if (!m.error) p.reply = m;
      if (p.index === state.current) render();
    } else if (!p) clearBusy('measure');
  },
  motion(m) {
    state.motions.set(`${m.a}-${m.b}`, m);
    if (state.motionWait === m.b) { clearBusy('motion'); state.motionWait = null; }
    renderMotion();
  },
  pose(m) { state.poses.set(m.index, m); renderMotion(); },
  trajectory(m) { state.trajectory = m.poses; renderMotion(); },
  plan(m) { state.plan = m; if (window.FindMePlan) FindMePlan.render(m, state.units); },  // plan.js
  error(m) {
    const hint = ERROR_HINTS[m.code] ? ' ' + ERROR_HINTS[m.code] : '';
    const box = notify(`Server: ${m.message}.${hint}`, 'error', m.code);
    if (m.key) { box.dataset.key = m.key; box.title = `about ${m.key}`; }
    const k = m.key || '';
    if (k.startsWith('frame/') || k.startsWith('hypotheses/')) clearBusy('upload');
    if (k.startsWith('selection/') || k.startsWith('scene/')) clearBusy('scene');
    if (k.startsWith('motion/') || k.startsWith('pose/') || k === 'trajectory') {
      clearBusy('motion'); state.motionWait = null;
    }
  },
};

// ------------------------------------------------------------------ wiring
function init() {
  initSettings();
  initCapture();
  initResults();
  $('units-btn').addEventListener('click', () => {
    state.units = state.units === 'm' ? 'ft' : 'm';
    $('units-btn').textContent = state.units === 'm' ? 'Show feet' : 'Show metres';
    $('units-btn').setAttribute('aria-pressed', String(state.units === 'ft'));
    render(); renderMotion();
    if (state.plan && window.FindMePlan) FindMePlan.render(state.plan, state.units);
  });
  $('new-session-btn').addEventListener('click', () => location.reload());
  connect();
}

// for tests and the curious: the pure conversions and the state
window.FindMe = {deviceGravityFromOrientation, deviceGravityFromMotion, deviceToCamera,
                 autoRotation, currentGravity, rotation, cameraHeading, currentHeading,
                 currentHeadingFields, state,
                 send, handle};
if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', init);
else init();
