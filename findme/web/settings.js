/* Find Me phone client: the camera settings (ES module): camera height, lens, phone model,
 * gravity typed or from the phone's motion sensors, and the photo orientation the sensor
 * conversion assumes.
 *
 * Gravity conversion (documented here and in the report):
 *   Device frame (W3C DeviceOrientation spec): x to the right of the screen, y to the top
 *   of the screen (the long side, natural portrait orientation), z out of the screen.
 *   - From deviceorientation (beta, gamma), the Z-X'-Y'' Tait-Bryan angles, gravity
 *     (pointing down) in the device frame is the third row of Rx(beta)·Ry(gamma), negated:
 *         g_dev = (cos(beta)·sin(gamma), -sin(beta), -cos(beta)·cos(gamma))
 *     (upright portrait: beta = 90° -> (0, -1, 0); flat, screen up: (0, 0, -1)).
 *   - From devicemotion, accelerationIncludingGravity is the reaction to gravity (flat,
 *     screen up: z = +9.8), so g_dev = -a / |a| (averaged over the last 0.5 s). Used only
 *     when deviceorientation gives no angles (its definition is the same on every browser).
 *   The rear camera looks along -z_dev. For a photo whose upright view is the device
 *   turned counter-clockwise by theta (0 portrait, 90 landscape with the phone's top to the
 *   left, 180, 270 top to the right), the image's right and down axes in the device frame
 *   are r = (cos t, -sin t, 0) and d = (-sin t, -cos t, 0), so in OpenCV camera axes
 *   (x right, y down, z forward):
 *         g_cam = (g_dev·r, g_dev·d, -g_dev.z)
 *     portrait:        ( gx, -gy, -gz)        landscape, top left:  (-gy, -gx, -gz)
 *     upside down:     (-gx,  gy, -gz)        landscape, top right: ( gy,  gx, -gz)
 *   The heading (which way the camera looks, turned about gravity) comes from
 *   deviceorientation's alpha, beta, gamma (R = Rz(alpha)·Rx(beta)·Ry(gamma), device to
 *   earth: x east or the start's, y north, z up): the rear camera's axis -z_dev is
 *         d = (-cos(a)·sin(g) - sin(a)·sin(b)·cos(g),  -sin(a)·sin(g) + cos(a)·sin(b)·cos(g),
 *              -cos(b)·cos(g))
 *   and the heading is atan2(d_x, d_y), growing as the camera turns right seen from above
 *   (upright portrait: -alpha). Only its differences between a session's photos matter
 *   (alpha is relative on most browsers: the yaw the gyroscope integrated since listening
 *   began), so a drifting gyroscope or a compass off by a constant does no harm. None when
 *   the camera looks within 20° of straight up or down (no horizontal direction to speak of).
 *   "Automatic" picks theta whose image-down axis is closest to gravity, as camera apps do
 *   when they decide a photo's orientation; the live camera uses the screen's angle
 *   (screen.orientation.angle), because its preview is upright for the screen.
 *
 * Where gravity comes from (shown under the photo, from the server's answer):
 *   - the phone's sensors, when allowed: listening starts by itself where no permission is
 *     asked (Android), or with "Turn on motion sensors" (iOS asks); a live-camera capture
 *     sends the reading of that moment, and "Use phone tilt now" fills the fields; the
 *     server refines a sent (or typed) gravity with the photo's own lines near it;
 *   - else the photo itself: the server estimates gravity from its vertical and horizontal
 *     lines (a photo from the camera app or the gallery was taken at another moment than
 *     any reading the page has, so the page does not guess);
 *   - else "level" is assumed, and the page warns that distances may be far off.
 * The lens: "From the photo" sends none, so the server reads the EXIF focal length (or, when
 * the page had to re-encode the photo and so drop its EXIF, the page sends the EXIF
 * 35 mm-equivalent focal length it read), else it assumes a typical phone camera.
 */
import {$, DEG, notify, state} from './common.js';

export const SENSOR_GRAVITY_SIGMA_DEG = 1.5;   // a phone's motion-sensor gravity in the hand (1-sigma per axis)
export const SENSOR_HEADING_SIGMA_DEG = 5;     // the gyroscope's heading between photos of a session (1-sigma)
// a compass's (deviceorientation with absolute: true, e.g. Firefox on Android): indoors it
// is off by tens of degrees near steel, the same way for every photo there; the server
// takes a photo file's compass bearing so too (frame_photo.EXIF_HEADING_SIGMA_RAD)
export const COMPASS_HEADING_SIGMA_DEG = 30;

// ------------------------------------------------------------------ gravity (pure)
export function normalize(v) {
  const n = Math.hypot(v[0], v[1], v[2]);
  return n > 0 ? v.map((x) => x / n) : null;
}
export function deviceGravityFromOrientation(betaDeg, gammaDeg) {
  const b = betaDeg / DEG, g = gammaDeg / DEG;
  return [Math.cos(b) * Math.sin(g), -Math.sin(b), -Math.cos(b) * Math.cos(g)];
}
export function deviceGravityFromMotion(ax, ay, az) { return normalize([-ax, -ay, -az]); }
export function cameraHeading(alphaDeg, betaDeg, gammaDeg) {
  const a = alphaDeg / DEG, b = betaDeg / DEG, g = gammaDeg / DEG;
  const dx = -Math.cos(a) * Math.sin(g) - Math.sin(a) * Math.sin(b) * Math.cos(g);
  const dy = -Math.sin(a) * Math.sin(g) + Math.cos(a) * Math.sin(b) * Math.cos(g);
  if (!(Math.hypot(dx, dy) >= Math.sin(20 / DEG))) return null;
  return Math.atan2(dx, dy) * DEG;
}
export function currentHeading() {   // the latest reading, if fresh (0.5 s)
  const h = state.sensors.heading;
  return h && performance.now() - h.t < 500 ? h.deg : null;
}
export function headingFields(deg, compass) {   // what a live capture's upload header says
  // of the heading: the gyroscope's (its own zero, +-5 deg) or a compass's ('?': true or
  // magnetic north, not said; +-30 deg)
  if (deg === null) return {};
  return compass ? {heading_deg: deg, heading_sigma_deg: COMPASS_HEADING_SIGMA_DEG, heading_ref: '?'}
    : {heading_deg: deg, heading_sigma_deg: SENSOR_HEADING_SIGMA_DEG};
}
export function currentHeadingFields() {   // headingFields of the latest fresh reading
  const h = state.sensors.heading;
  return headingFields(currentHeading(), Boolean(h && h.compass));
}
export function deviceToCamera(g, thetaDeg) {
  const t = thetaDeg / DEG;
  const r = [Math.cos(t), -Math.sin(t)], d = [-Math.sin(t), -Math.cos(t)];
  const c = [g[0] * r[0] + g[1] * r[1], g[0] * d[0] + g[1] * d[1], -g[2]];
  return c.map((x) => (Math.abs(x) < 1e-12 ? 0 : x));
}
export function autoRotation(g) {
  let best = 0, bestDot = -Infinity;
  for (const t of [0, 90, 180, 270]) {
    const dot = deviceToCamera(g, t)[1];
    if (dot > bestDot + 1e-9) { best = t; bestDot = dot; }
  }
  return best;
}
// ------------------------------------------------------------------ the form
export function num(id) {
  const v = $(id).value.trim();
  if (v === '') return null;
  const x = Number(v);
  if (!Number.isFinite(x)) throw new Error(`${id} must be a number`);
  return x;
}
export function lensFromForm(dims, exifFocal35) {
  const kind = $('lens').value;
  if (kind === 'auto') {   // the server reads EXIF; unless the page re-encoded (EXIF gone)
    return exifFocal35 ? {kind: 'focal35', focal35_mm: exifFocal35} : {kind: 'default'};
  }
  if (kind === 'typical') return {kind: 'focal35', focal35_mm: 26};
  if (kind === 'focal35') {
    const f = num('focal35');
    if (f === null || f <= 0) throw new Error('Enter the 35 mm-equivalent focal length in mm.');
    return {kind, focal35_mm: f};
  }
  if (kind === 'hfov') {
    const h = num('hfov');
    if (h === null || !(h > 0 && h < 180)) throw new Error('Enter a field of view between 0 and 180°.');
    return {kind, hfov_deg: h};
  }
  if (kind === 'intrinsics') {
    const k = {kind, fx: num('fx'), fy: num('fy'), cx: num('cx'), cy: num('cy')};
    if ([k.fx, k.fy, k.cx, k.cy].includes(null)) throw new Error('Fill in fx, fy, cx and cy, or choose another lens.');
    if (dims) { k.width = dims.w; k.height = dims.h; }
    return k;
  }
  return {kind: 'default'};
}
export function gravityFromForm() {
  const g = ['gx', 'gy', 'gz'].map(num);
  if (g.every((x) => x === null)) return null;
  if (g.includes(null)) throw new Error('Fill in all three gravity numbers, or clear them.');
  return g;
}
export function heightFromForm() {
  const h = num('height');
  if (h !== null && !(h > 0 && h <= 100)) throw new Error('The camera height must be between 0 and 100 m.');
  return h;
}
// ------------------------------------------------------------------ sensors + camera
export function pushSample(g, source) {
  if (!g || g.some((x) => !Number.isFinite(x))) return;
  const now = performance.now();
  const s = state.sensors;
  if (source === 'motion' && s.samples.length && s.samples[s.samples.length - 1].source === 'orientation' &&
      now - s.samples[s.samples.length - 1].t < 500) return;  // orientation is preferred
  s.samples.push({t: now, g, source});
  while (s.samples.length && now - s.samples[0].t > 500) s.samples.shift();
  s.source = source;
  const c = deviceToCamera(currentGravity(), rotation());
  $('sensor-readout').textContent = `Phone tilt (${source}), camera axes: ` +
    c.map((x) => x.toFixed(3)).join(', ');
  $('tilt-btn').disabled = false;
}
export function currentGravity() {
  const s = state.sensors.samples;
  if (!s.length) return null;
  const m = [0, 0, 0];
  for (const q of s) for (let i = 0; i < 3; i++) m[i] += q.g[i];
  return normalize(m);
}
export function rotation(live = false) {
  const sel = $('orientation').value;
  if (sel !== 'auto') return Number(sel);
  if (live) {
    const a = (screen.orientation && screen.orientation.angle) ?? window.orientation ?? 0;
    return ((a % 360) + 360) % 360;
  }
  const g = currentGravity();
  return g ? autoRotation(g) : 0;
}
export function sensorsNeedAsking() {
  return [window.DeviceOrientationEvent, window.DeviceMotionEvent]
    .some((cls) => cls && typeof cls.requestPermission === 'function');
}
export async function startSensors(quiet = false) {
  if (!window.isSecureContext) {
    notify('Motion sensors need a secure page (HTTPS or localhost); type gravity in instead.', 'warn', 'INSECURE');
    return;
  }
  try {
    for (const cls of [window.DeviceOrientationEvent, window.DeviceMotionEvent]) {
      if (cls && typeof cls.requestPermission === 'function') {
        const r = await cls.requestPermission();
        if (r !== 'granted') throw new Error('permission was not given');
      }
    }
  } catch (e) {
    notify(`Motion sensors are not available: ${e.message}.`, 'warn', 'SENSORS');
    return;
  }
  if (state.sensors.on) return;
  state.sensors.on = true;
  window.addEventListener('deviceorientation', (e) => {
    if (e.beta !== null && e.gamma !== null) pushSample(deviceGravityFromOrientation(e.beta, e.gamma), 'orientation');
    const h = e.alpha !== null && e.beta !== null && e.gamma !== null ? cameraHeading(e.alpha, e.beta, e.gamma) : null;
    if (h !== null && Number.isFinite(h)) {
      state.sensors.heading = {t: performance.now(), deg: h, compass: e.absolute === true};
    }
    state.sensors.angles = [e.alpha, e.beta, e.gamma];   // as read (for tests and the curious)
  });
  window.addEventListener('devicemotion', (e) => {
    const a = e.accelerationIncludingGravity;
    if (a && a.x !== null) pushSample(deviceGravityFromMotion(a.x, a.y, a.z), 'motion');
  });
  $('sensors-btn').textContent = 'Motion sensors on';
  if (!quiet) {
    setTimeout(() => {
      if (!state.sensors.samples.length) notify('This device reports no motion sensors; type gravity in instead.', 'warn', 'SENSORS');
    }, 2000);
  }
}
export function fillGravity(live) {
  const g = currentGravity();
  if (!g) { notify('No phone tilt yet: turn on the motion sensors.', 'warn', 'SENSORS'); return false; }
  const c = deviceToCamera(g, rotation(live));
  ['gx', 'gy', 'gz'].forEach((id, i) => { $(id).value = c[i].toFixed(4); });
  state.sensors.filled = ['gx', 'gy', 'gz'].map((id) => $(id).value);   // from the sensors
  return true;
}

// ------------------------------------------------------------------ wiring
export function lensFields() {
  const k = $('lens').value;
  document.querySelectorAll('.lens-fields').forEach((d) => { d.hidden = d.dataset.lens !== k; });
}
export function initSettings() {
  $('lens').addEventListener('change', lensFields);
  lensFields();
  $('sensors-btn').addEventListener('click', () => startSensors(false));
  $('tilt-btn').addEventListener('click', () => fillGravity(false));
  $('gravity-clear-btn').addEventListener('click', () => ['gx', 'gy', 'gz'].forEach((id) => { $(id).value = ''; }));
  if (window.isSecureContext && !sensorsNeedAsking() &&
      (window.DeviceOrientationEvent || window.DeviceMotionEvent)) startSensors(true);
}
