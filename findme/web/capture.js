/* Find Me phone client: taking or picking a photo and sending it (ES module).
 *
 * A photo goes to the gateway as one binary WebSocket message:
 *   [u32 big-endian n][n bytes JSON header][photo bytes]
 * the header carrying the lens, gravity (typed or the phone's sensors, with its 1-sigma),
 * camera height, phone model and capture time (settings.js). A JPEG whose EXIF turns it, or
 * a format the server may not read (HEIC on Safari), is re-encoded upright through a canvas
 * first. The live camera (secure pages only) sends the motion sensors' reading of the moment
 * the shutter is pressed.
 */
import {$, ERROR_HINTS, clearBusy, mb, notify, send, setBusy, state} from './common.js';
import {SENSOR_GRAVITY_SIGMA_DEG, currentGravity, deviceToCamera, gravityFromForm,
        heightFromForm, lensFromForm, rotation} from './settings.js';

// ------------------------------------------------------------------ uploading
export function sniff(b) {
  if (b[0] === 0xff && b[1] === 0xd8 && b[2] === 0xff) return 'jpeg';
  if (b[0] === 0x89 && b[1] === 0x50 && b[2] === 0x4e && b[3] === 0x47) return 'png';
  if (b[0] === 0x52 && b[1] === 0x49 && b[2] === 0x46 && b[3] === 0x46 &&
      b[8] === 0x57 && b[9] === 0x45 && b[10] === 0x42 && b[11] === 0x50) return 'webp';
  return null;
}
export function exifFacts(b) {  // JPEG EXIF: orientation (0x0112, 1 when absent) and the
  // 35 mm-equivalent focal length (Exif IFD 0x8769 -> 0xA405, null when absent)
  const out = {orientation: 1, focal35: null};
  try {
    const dv = new DataView(b.buffer, b.byteOffset, b.byteLength);
    let i = 2;
    while (i + 4 <= b.length && b[i] === 0xff) {
      const marker = b[i + 1], len = dv.getUint16(i + 2);
      if (marker === 0xe1 && dv.getUint32(i + 4) === 0x45786966) {
        const t = i + 10, le = dv.getUint16(t) === 0x4949;
        const entries = (off) => {
          const n = dv.getUint16(off, le), list = [];
          for (let k = 0; k < n; k++) list.push(off + 2 + 12 * k);
          return list;
        };
        for (const e of entries(t + dv.getUint32(t + 4, le))) {
          const tag = dv.getUint16(e, le);
          if (tag === 0x0112) out.orientation = dv.getUint16(e + 8, le);
          if (tag === 0x8769) {
            for (const f of entries(t + dv.getUint32(e + 8, le))) {
              if (dv.getUint16(f, le) === 0xa405) out.focal35 = dv.getUint16(f + 8, le) || null;
            }
          }
        }
        return out;
      }
      if (marker === 0xda) return out;
      i += 2 + len;
    }
  } catch (e) { /* a broken EXIF block: what was read so far */ }
  return out;
}
export async function reencode(blob) {  // upright JPEG through a canvas (EXIF rotation, HEIC, ...)
  const bmp = await createImageBitmap(blob, {imageOrientation: 'from-image'});
  const c = document.createElement('canvas');
  c.width = bmp.width; c.height = bmp.height;
  c.getContext('2d').drawImage(bmp, 0, 0);
  const out = await new Promise((res) => c.toBlob(res, 'image/jpeg', 0.95));
  return out;
}
export function imageSize(url) {
  return new Promise((resolve, reject) => {
    const img = new Image();
    img.onload = () => resolve({w: img.naturalWidth, h: img.naturalHeight});
    img.onerror = () => reject(new Error('not an image'));
    img.src = url;
  });
}

export async function upload(file, sensorGravity = null) {
  if (!file) return;
  if (!state.session) { notify('Not connected to the server yet.', 'error', 'CLOSED'); return; }
  if (state.photos.length >= state.limits.max_photos) {
    notify(`This session already has ${state.limits.max_photos} photos; start a new session.`);
    return;
  }
  if (file.size > state.limits.max_upload_bytes) {
    notify(`This file is ${mb(file.size)}; the server takes photos up to ` +
           `${mb(state.limits.max_upload_bytes)}. ${ERROR_HINTS.TOO_LARGE}`, 'error', 'TOO_LARGE');
    return;
  }
  let header;
  const id = 'u' + (++state.seq);
  setBusy('upload', 'Sending the photo…');
  try {
    let blob = file;
    let bytes = new Uint8Array(await file.arrayBuffer());
    const fmt = sniff(bytes);
    const exif = fmt === 'jpeg' ? exifFacts(bytes) : {orientation: 1, focal35: null};
    let reencoded = false;
    if (!fmt || (fmt === 'jpeg' && exif.orientation > 1)) {
      // the browser can show it upright (EXIF rotation) or decode it (HEIC on Safari): send
      // the pixels as shown; if it cannot decode it either, the server says what is wrong
      try {
        const up = await reencode(file);
        if (up) { blob = up; bytes = new Uint8Array(await up.arrayBuffer()); reencoded = true; }
      } catch (e) { /* not decodable here: the server judges */ }
    }
    const url = URL.createObjectURL(blob);
    const dims = await imageSize(url).catch(() => null);
    const typed = gravityFromForm();
    const gravity = sensorGravity || typed;
    const filled = state.sensors.filled &&
      ['gx', 'gy', 'gz'].every((id, i) => $(id).value === state.sensors.filled[i]);
    const fromSensors = Boolean(sensorGravity || (typed && filled));
    header = {type: 'frame', id, lens: lensFromForm(dims, reencoded ? exif.focal35 : null), gravity,
              // a hand-held reading is good to a degree or two: the server weighs it so
              // against the photo's own lines (gravity_fusion)
              gravity_sigma_deg: gravity && fromSensors ? SENSOR_GRAVITY_SIGMA_DEG : undefined,
              camera_height_m: heightFromForm(), device: $('device').value.trim(),
              capture_time_ms: file.lastModified || Date.now()};
    const head = new TextEncoder().encode(JSON.stringify(header));
    const buf = new Uint8Array(4 + head.length + bytes.length);
    new DataView(buf.buffer).setUint32(0, head.length);
    buf.set(head, 4);
    buf.set(bytes, 4 + head.length);
    state.pending.set(id, {url, name: file.name, gravity,
                           gravitySource: fromSensors ? 'sensors' : typed ? 'typed' : null});
    if (!send(buf.buffer)) { state.pending.delete(id); clearBusy('upload'); }
  } catch (e) {
    clearBusy('upload');
    notify(e.message, 'error', 'FORM');
  }
}

// ------------------------------------------------------------------ live camera
export async function startLive() {
  try {
    const stream = await navigator.mediaDevices.getUserMedia(
      {video: {facingMode: {ideal: 'environment'}, width: {ideal: 1920}, height: {ideal: 1440}}, audio: false});
    $('live-video').srcObject = stream;
    $('live').hidden = false;
  } catch (e) {
    notify(`The camera could not be opened: ${e.message}. Use “Take photo” instead.`, 'warn', 'CAMERA');
  }
}
export function stopLive() {
  const v = $('live-video');
  if (v.srcObject) v.srcObject.getTracks().forEach((t) => t.stop());
  v.srcObject = null;
  $('live').hidden = true;
}
export function shutter() {
  const v = $('live-video');
  if (!v.videoWidth) return;
  const c = document.createElement('canvas');
  c.width = v.videoWidth; c.height = v.videoHeight;
  c.getContext('2d').drawImage(v, 0, 0);
  const g = currentGravity();
  const sensed = g ? deviceToCamera(g, rotation(true)) : null;
  c.toBlob((b) => upload(new File([b], 'live.jpg', {type: 'image/jpeg', lastModified: Date.now()}),
                         sensed), 'image/jpeg', 0.92);
}

// ------------------------------------------------------------------ wiring
export function initCapture() {
  for (const id of ['camera-input', 'file-input']) {
    $(id).addEventListener('change', (e) => {
      const f = e.target.files && e.target.files[0];
      e.target.value = '';
      upload(f);
    });
  }
  if (window.isSecureContext && navigator.mediaDevices && navigator.mediaDevices.getUserMedia) {
    $('live-btn').hidden = false;
    $('live-btn').addEventListener('click', startLive);
    $('shutter-btn').addEventListener('click', shutter);
    $('live-close-btn').addEventListener('click', stopLive);
  }
}
