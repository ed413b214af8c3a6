/* Find Me phone client: taking or picking a photo and sending it (ES module).
 *
 * A photo goes to the gateway as one binary WebSocket message:
 *   [u32 big-endian n][n bytes JSON header][photo bytes]
 * the header carrying the lens, gravity (typed or the phone's sensors, with its 1-sigma),
 * camera height, phone model and capture time (settings.js). A photo longer than 1600 px, a
 * JPEG whose EXIF turns it, or a format the server may not read (HEIC on Safari), is
 * re-encoded upright through a canvas first, at most 1600 px long (the header's ``scale``
 * and typed intrinsics scaled to match). The live camera (secure pages only) sends the motion sensors' reading of the moment
 * the shutter is pressed: gravity, and the heading (which way the phone looked, for the
 * floor plan's placement: photos that share nothing cannot tell a room's twin turns apart);
 * a photo file sends its EXIF compass bearing instead, when it has one.
 */
import {$, ERROR_HINTS, clearBusy, mb, notify, send, setBusy, state} from './common.js';
import {SENSOR_GRAVITY_SIGMA_DEG, currentGravity, currentHeadingFields, deviceToCamera,
        gravityFromForm, heightFromForm, lensFromForm, rotation} from './settings.js';

// ------------------------------------------------------------------ uploading
export function sniff(b) {
  if (b[0] === 0xff && b[1] === 0xd8 && b[2] === 0xff) return 'jpeg';
  if (b[0] === 0x89 && b[1] === 0x50 && b[2] === 0x4e && b[3] === 0x47) return 'png';
  if (b[0] === 0x52 && b[1] === 0x49 && b[2] === 0x46 && b[3] === 0x46 &&
      b[8] === 0x57 && b[9] === 0x45 && b[10] === 0x42 && b[11] === 0x50) return 'webp';
  return null;
}
export function exifFacts(b) {  // JPEG EXIF: orientation (0x0112, 1 when absent), the
  // 35 mm-equivalent focal length (Exif IFD 0x8769 -> 0xA405, null when absent) and the
  // compass bearing the camera looked along (GPS IFD 0x8825 -> GPSImgDirection 0x0011, a
  // rational in [0, 360], and its reference 0x0010, 'T' or 'M'; null / '' when absent)
  const out = {orientation: 1, focal35: null, heading: null, headingRef: ''};
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
          if (tag === 0x8825) {
            for (const f of entries(t + dv.getUint32(e + 8, le))) {
              const g = dv.getUint16(f, le);
              if (g === 0x0010) out.headingRef = String.fromCharCode(b[f + 8]).trim();
              if (g === 0x0011) {
                const at = t + dv.getUint32(f + 8, le);
                const d = dv.getUint32(at, le) / dv.getUint32(at + 4, le);
                out.heading = Number.isFinite(d) && d >= 0 && d <= 360 ? d % 360 : null;
              }
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
// the long side of the photo sent (the paper's own argument: bandwidth): a 12 MP photo is
// sent at 1600x1200 (~0.4 MB instead of ~4 MB); the server works at 640 px anyway
const MAX_UPLOAD_SIDE = 1600;
export async function reencode(blob, always) {
  // upright JPEG through a canvas (EXIF rotation, HEIC, ...), at most MAX_UPLOAD_SIDE on
  // its long side: {blob, scale} (scale = sent pixels per photo pixel), or null when the
  // photo is sent as it is (upright already, small enough)
  const bmp = await createImageBitmap(blob, {imageOrientation: 'from-image'});
  const scale = Math.min(1, MAX_UPLOAD_SIDE / Math.max(bmp.width, bmp.height));
  const over = bmp.width * bmp.height > (state.limits.max_pixels || 50e6);
  // over the server's pixel limit: sent as it is, and the server says so
  if (over || (!always && scale === 1)) { bmp.close(); return null; }
  const c = document.createElement('canvas');
  c.width = Math.round(bmp.width * scale); c.height = Math.round(bmp.height * scale);
  const g = c.getContext('2d');
  g.imageSmoothingQuality = 'high';
  g.drawImage(bmp, 0, 0, c.width, c.height);
  const sent = c.width / bmp.width;   // exactly, after rounding to whole pixels
  bmp.close();
  const out = await new Promise((res) => c.toBlob(res, 'image/jpeg', 0.92));
  return out && {blob: out, scale: sent};
}
export function scaledLens(lens, s, dims) {  // intrinsics typed for the photo -> the photo sent
  if (lens.kind !== 'intrinsics' || s === 1) return lens;   // the others do not change
  const k = {...lens, fx: lens.fx * s, fy: lens.fy * s,
             cx: (lens.cx + 0.5) * s - 0.5, cy: (lens.cy + 0.5) * s - 0.5};   // pixel centres
  if (dims) { k.width = dims.w; k.height = dims.h; }
  return k;
}
export function imageSize(url) {
  return new Promise((resolve, reject) => {
    const img = new Image();
    img.onload = () => resolve({w: img.naturalWidth, h: img.naturalHeight});
    img.onerror = () => reject(new Error('not an image'));
    img.src = url;
  });
}

export async function upload(file, sensorGravity = null, sensorHeading = {}) {
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
    let reencoded = false, scale = 1;
    // the browser can show it upright (EXIF rotation) or decode it (HEIC on Safari): send
    // the pixels as shown, at most MAX_UPLOAD_SIDE px long; if it cannot decode it
    // either, the server says what is wrong
    try {
      const up = await reencode(file, !fmt || (fmt === 'jpeg' && exif.orientation > 1));
      if (up) {
        blob = up.blob; bytes = new Uint8Array(await up.blob.arrayBuffer());
        reencoded = true; scale = up.scale;
      }
    } catch (e) { /* not decodable here: the server judges */ }
    const url = URL.createObjectURL(blob);
    const dims = await imageSize(url).catch(() => null);
    const typed = gravityFromForm();
    const gravity = sensorGravity || typed;
    const filled = state.sensors.filled &&
      ['gx', 'gy', 'gz'].every((id, i) => $(id).value === state.sensors.filled[i]);
    const fromSensors = Boolean(sensorGravity || (typed && filled));
    // the EXIF focal length (35 mm equivalent: the same for any size) goes with a
    // re-encoded photo (EXIF gone); typed intrinsics are scaled to the pixels sent
    header = {type: 'frame', id, gravity, scale,
              lens: scaledLens(lensFromForm(dims && {w: Math.round(dims.w / scale),
                                                    h: Math.round(dims.h / scale)},
                                            reencoded ? exif.focal35 : null), scale, dims),
              // a hand-held reading is good to a degree or two: the server weighs it so
              // against the photo's own lines (gravity_fusion)
              gravity_sigma_deg: gravity && fromSensors ? SENSOR_GRAVITY_SIGMA_DEG : undefined,
              camera_height_m: heightFromForm(), device: $('device').value.trim(),
              capture_time_ms: file.lastModified || Date.now()};
    if (sensorHeading.heading_deg !== undefined) {   // a live capture: which way the phone
      Object.assign(header, sensorHeading);           // looked (headingFields), for the plan
    } else if (exif.heading !== null) {   // a file's compass bearing (lost if re-encoded);
      header.heading_deg = exif.heading;  // the server takes it at a compass's 1-sigma
      header.heading_ref = ['T', 'M'].includes(exif.headingRef) ? exif.headingRef : '?';
    }
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
  const heading = currentHeadingFields();
  c.toBlob((b) => upload(new File([b], 'live.jpg', {type: 'image/jpeg', lastModified: Date.now()}),
                         sensed, heading), 'image/jpeg', 0.92);
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
