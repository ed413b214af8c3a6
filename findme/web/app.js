/* Find Me phone client: capture a photo, pick the floor boundary, tap points, see motion.
 *
 * Talks to the gateway (services/gateway.py) over one WebSocket = one session:
 *   binary  [u32 big-endian n][n bytes JSON header][photo bytes]   a photo
 *   text    {"type": "select", index, rank, camera_height_m}         another hypothesis
 *   text    {"type": "measure", id, index, pixels: [[u, v], ...]}    3D of tapped pixels
 * and gets JSON: hello, frame, refused, hypotheses, selection, scene, measure, motion, pose,
 * trajectory, plan (drawn by plan.js), error. Pixels follow the bus convention: (0, 0) is the centre of the
 * top-left pixel.
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
'use strict';
(function () {
  const $ = (id) => document.getElementById(id);
  const SVG = 'http://www.w3.org/2000/svg';
  const COLORS = ['#e6194b', '#3cb44b', '#4363d8', '#f58231', '#911eb4', '#00a5b8',
                  '#f032e6', '#7a9c00', '#9a6324', '#469990'];
  const DEG = 180 / Math.PI;
  const SENSOR_GRAVITY_SIGMA_DEG = 1.5;   // a phone's motion-sensor gravity in the hand (1-sigma per axis)

  const state = {
    ws: null, session: null, services: [], seq: 0, measureSeq: 0,
    limits: {max_upload_bytes: 15 * 1024 * 1024, max_measure_pixels: 64, max_photos: 100},
    photos: [], current: -1, pending: new Map(), busy: new Map(), units: 'm',
    motions: new Map(), poses: new Map(), trajectory: null, motionTimer: null,
    sensors: {on: false, samples: [], source: ''},
  };

  // ------------------------------------------------------------------ gravity (pure)
  function normalize(v) {
    const n = Math.hypot(v[0], v[1], v[2]);
    return n > 0 ? v.map((x) => x / n) : null;
  }
  function deviceGravityFromOrientation(betaDeg, gammaDeg) {
    const b = betaDeg / DEG, g = gammaDeg / DEG;
    return [Math.cos(b) * Math.sin(g), -Math.sin(b), -Math.cos(b) * Math.cos(g)];
  }
  function deviceGravityFromMotion(ax, ay, az) { return normalize([-ax, -ay, -az]); }
  function deviceToCamera(g, thetaDeg) {
    const t = thetaDeg / DEG;
    const r = [Math.cos(t), -Math.sin(t)], d = [-Math.sin(t), -Math.cos(t)];
    const c = [g[0] * r[0] + g[1] * r[1], g[0] * d[0] + g[1] * d[1], -g[2]];
    return c.map((x) => (Math.abs(x) < 1e-12 ? 0 : x));
  }
  function autoRotation(g) {
    let best = 0, bestDot = -Infinity;
    for (const t of [0, 90, 180, 270]) {
      const dot = deviceToCamera(g, t)[1];
      if (dot > bestDot + 1e-9) { best = t; bestDot = dot; }
    }
    return best;
  }

  // ------------------------------------------------------------------ small helpers
  function el(tag, attrs = {}, text) {
    const e = tag.startsWith('svg:') ? document.createElementNS(SVG, tag.slice(4))
                                     : document.createElement(tag);
    for (const [k, v] of Object.entries(attrs)) if (v !== undefined && v !== null) e.setAttribute(k, v);
    if (text !== undefined) e.textContent = text;
    return e;
  }
  const mb = (n) => (n / 1e6).toFixed(1) + ' MB';
  function fmtLen(m, digits = 3) {
    if (m === null || m === undefined) return '–';
    if (state.units === 'm') return m.toFixed(digits) + ' m';
    const inches = Math.abs(m) / 0.0254, sign = m < 0 ? '−' : '';
    const ft = Math.floor(inches / 12);
    return `${sign}${ft} ft ${(inches - 12 * ft).toFixed(1)} in`;
  }
  function fmtCoord(m) {
    return state.units === 'm' ? (m >= 0 ? '+' : '') + m.toFixed(2)
                               : (m >= 0 ? '+' : '') + (m / 0.3048).toFixed(2);
  }
  function fmtSigma(m) {
    if (m === null || m === undefined) return '';
    return state.units === 'm' ? ` ± ${m.toFixed(3)} m` : ` ± ${(m / 0.0254).toFixed(1)} in`;
  }

  function notify(text, kind = 'error', code = '') {
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
  const ERROR_HINTS = {
    TOO_LARGE: 'Try a smaller photo.', BAD_IMAGE: 'Send a JPEG, PNG or WebP photo.',
    BAD_CAMERA: 'Check the camera settings.', OVERLOADED: 'Try again in a moment.',
  };

  function setBusy(key, text) { state.busy.set(key, text); renderBusy(); }
  function clearBusy(key) { state.busy.delete(key); renderBusy(); }
  function renderBusy() {
    const b = $('busy');
    const texts = [...state.busy.values()];
    b.hidden = texts.length === 0;
    $('busy-text').textContent = texts[texts.length - 1] || '';
    document.body.setAttribute('aria-busy', texts.length ? 'true' : 'false');
    document.body.dataset.busy = texts.length ? [...state.busy.keys()].join(' ') : '';
  }

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
  function setStatus(s, text) {
    const e = $('status');
    e.dataset.state = s;
    e.textContent = text;
  }
  function send(obj) {
    if (!state.ws || state.ws.readyState !== WebSocket.OPEN) {
      notify('Not connected to the server. Start a new session.', 'error', 'CLOSED');
      return false;
    }
    state.ws.send(typeof obj === 'string' || obj instanceof ArrayBuffer ? obj : JSON.stringify(obj));
    return true;
  }

  // ------------------------------------------------------------------ uploading
  function sniff(b) {
    if (b[0] === 0xff && b[1] === 0xd8 && b[2] === 0xff) return 'jpeg';
    if (b[0] === 0x89 && b[1] === 0x50 && b[2] === 0x4e && b[3] === 0x47) return 'png';
    if (b[0] === 0x52 && b[1] === 0x49 && b[2] === 0x46 && b[3] === 0x46 &&
        b[8] === 0x57 && b[9] === 0x45 && b[10] === 0x42 && b[11] === 0x50) return 'webp';
    return null;
  }
  function exifFacts(b) {  // JPEG EXIF: orientation (0x0112, 1 when absent) and the
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
  // the long side of the photo sent (the paper's own argument: bandwidth): a 12 MP photo is
  // sent at 1600x1200 (~0.4 MB instead of ~4 MB); the server works at 640 px anyway
  const MAX_UPLOAD_SIDE = 1600;
  async function reencode(blob, always) {
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
  function scaledLens(lens, s, dims) {  // intrinsics typed for the photo -> the photo sent
    if (lens.kind !== 'intrinsics' || s === 1) return lens;   // the others do not change
    const k = {...lens, fx: lens.fx * s, fy: lens.fy * s,
               cx: (lens.cx + 0.5) * s - 0.5, cy: (lens.cy + 0.5) * s - 0.5};   // pixel centres
    if (dims) { k.width = dims.w; k.height = dims.h; }
    return k;
  }
  function imageSize(url) {
    return new Promise((resolve, reject) => {
      const img = new Image();
      img.onload = () => resolve({w: img.naturalWidth, h: img.naturalHeight});
      img.onerror = () => reject(new Error('not an image'));
      img.src = url;
    });
  }
  function num(id) {
    const v = $(id).value.trim();
    if (v === '') return null;
    const x = Number(v);
    if (!Number.isFinite(x)) throw new Error(`${id} must be a number`);
    return x;
  }
  function lensFromForm(dims, exifFocal35) {
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
  function gravityFromForm() {
    const g = ['gx', 'gy', 'gz'].map(num);
    if (g.every((x) => x === null)) return null;
    if (g.includes(null)) throw new Error('Fill in all three gravity numbers, or clear them.');
    return g;
  }
  function heightFromForm() {
    const h = num('height');
    if (h !== null && !(h > 0 && h <= 100)) throw new Error('The camera height must be between 0 and 100 m.');
    return h;
  }

  async function upload(file, sensorGravity = null) {
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

  // ------------------------------------------------------------------ server messages
  const photoAt = (n) => state.photos.find((p) => p.index === n);
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
                 reply: null, measureId: 0, camera: null,
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

  function expectMotion(n) {
    if (!state.services.includes('odometry')) { renderMotion(); return; }
    if ([...state.motions.values()].some((m) => m.b === n)) return;
    state.motionWait = n;
    setBusy('motion', 'Estimating how you moved…');
    clearTimeout(state.motionTimer);
    state.motionTimer = setTimeout(() => {
      if (state.motionWait === n) {
        clearBusy('motion'); state.motionWait = null;
        notify(`No motion estimate for photo ${n + 1} arrived within 60 s.`, 'warn', 'TIMEOUT');
      }
    }, 60000);
  }

  // ------------------------------------------------------------------ actions
  function selectRank(rank) {
    const p = photoAt(state.current);
    if (!p || !p.hyps) return;
    let h = null;
    try { h = heightFromForm(); } catch (e) { notify(e.message, 'error', 'FORM'); return; }
    if (send({type: 'select', index: p.index, rank, camera_height_m: h})) {
      p.rank = rank;
      setBusy('scene', 'Building the 3D scene…');
      render();
    }
  }
  function measure(p) {
    if (!p.points.length) { p.reply = null; return; }
    p.measureId = ++state.measureSeq;
    if (send({type: 'measure', id: p.measureId, index: p.index, pixels: p.points})) {
      setBusy('measure', 'Measuring…');
    }
  }
  function onTap(ev) {
    const p = photoAt(state.current);
    if (!p) return;
    const r = $('photo').getBoundingClientRect();
    const x = ev.clientX - r.left, y = ev.clientY - r.top;
    if (x < 0 || y < 0 || x > r.width || y > r.height || !r.width) {
      notify('That tap was outside the photo: tap on the photo itself.', 'warn', 'OUTSIDE');
      return;
    }
    if (!p.hyps || !p.hyps.length) {
      notify('Wait for the floor boundary before tapping points.', 'warn', 'NOT_READY');
      return;
    }
    if (p.points.length >= state.limits.max_measure_pixels) {
      notify(`At most ${state.limits.max_measure_pixels} points: clear some first.`, 'warn', 'LIMIT');
      return;
    }
    const u = Math.min(p.width - 1, Math.max(0, Math.round(x * p.width / r.width - 0.5)));
    const v = Math.min(p.height - 1, Math.max(0, Math.round(y * p.height / r.height - 0.5)));
    p.points.push([u, v]);
    p.reply = null;
    render();
    if (p.sceneRank) measure(p);
  }

  // ------------------------------------------------------------------ rendering
  function show(n) {
    state.current = n;
    $('result').hidden = false;
    render();
    renderMotion();
  }
  function render() {
    const p = photoAt(state.current);
    const tabs = $('photo-tabs');
    tabs.replaceChildren(...state.photos.map((q) => {
      const b = el('button', {type: 'button', class: 'tab', 'data-index': q.index,
                              'aria-selected': String(q.index === state.current)}, `Photo ${q.index + 1}`);
      b.addEventListener('click', () => show(q.index));
      return b;
    }));
    if (!p) return;
    const img = $('photo');
    if (img.getAttribute('src') !== p.url) img.src = p.url;
    const frame = $('frame');
    frame.dataset.index = p.index;
    frame.dataset.rank = p.rank;
    frame.dataset.sceneRank = p.sceneRank;
    const svg = $('overlay');
    svg.setAttribute('viewBox', `-0.5 -0.5 ${p.width} ${p.height}`);
    svg.setAttribute('preserveAspectRatio', 'none');
    svg.replaceChildren();
    const hyps = p.hyps || [];
    const showAll = $('show-all').checked;
    for (const h of hyps) {
      if (!showAll && h.rank !== p.rank) continue;
      drawPolyline(svg, h, COLORS[(h.rank - 1) % COLORS.length], h.rank === p.rank);
    }
    drawPoints(svg, p);
    // chips: re-used while they show the same set (a tap must not lose its target)
    const chips = $('hyp-chips');
    if (chips.dataset.key === `${p.index}/${hyps.length}`) {
      for (const b of chips.children) b.setAttribute('aria-pressed', String(Number(b.dataset.rank) === p.rank));
    } else chips.replaceChildren(...hyps.map((h) => {
      const b = el('button', {type: 'button', class: 'chip', 'data-rank': h.rank,
                              'aria-pressed': String(h.rank === p.rank),
                              title: `score ${h.score.toFixed(2)}, edge support ${(100 * h.support).toFixed(0)}%`});
      const sw = el('span', {class: 'swatch'});
      sw.style.background = COLORS[(h.rank - 1) % COLORS.length];
      b.append(sw, document.createTextNode(h.rank === 1 ? '1 (best)' : String(h.rank)));
      b.addEventListener('click', () => selectRank(h.rank));
      return b;
    }));
    chips.dataset.key = `${p.index}/${hyps.length}`;
    let status;
    if (!p.hyps) status = `Photo ${p.index + 1} (${p.width}×${p.height}): finding the floor boundary…`;
    else if (!hyps.length) status = `Photo ${p.index + 1}: no floor boundary found (${p.reason}).`;
    else {
      status = `Photo ${p.index + 1}: ${hyps.length} boundary hypotheses; showing ` +
               `${p.rank}${p.by === 'user' ? ' (your choice)' : p.rank === 1 ? ' (best)' : ''}.`;
      if (p.sceneRank && p.sceneRank === p.rank) {
        status += p.metric ? ` Camera ${fmtLen(p.height_m, 2)} above the floor.`
                           : ' No camera height: distances are in camera heights.';
      }
    }
    $('photo-status').textContent = status;
    renderSources(p);
    renderPoints(p);
  }
  function renderSources(p) {   // where the lens and gravity of this photo came from
    const e = $('sources'), c = p.camera;
    if (!c) { e.textContent = ''; e.dataset.gravitySource = ''; e.dataset.lensSource = ''; return; }
    const lens = {input: 'as set', exif: "from the photo's EXIF", default: 'a typical phone assumed'}[c.lens_source] || '';
    const given = p.gravitySent === 'sensors' ? "from the phone's motion sensors" : 'as typed';
    const g = c.gravity_source === 'input' ? given
      : c.gravity_source === 'input+image' ? `${given}, refined by the photo's lines (± ${c.gravity_sigma_deg.toFixed(1)}°)`
      : c.gravity_source === 'image' ? `estimated from the photo's lines (± ${c.gravity_sigma_deg.toFixed(1)}°)`
      : `NOT KNOWN: level assumed (± ${c.gravity_sigma_deg.toFixed(0)}°)`;
    const pitch = Math.asin(Math.max(-1, Math.min(1, c.gravity[2]))) * DEG;
    e.textContent = `Lens ${c.hfov_deg ? c.hfov_deg.toFixed(0) + '° wide' : ''}, ${lens}. ` +
                    `Tilt ${pitch.toFixed(1)}° down, ${g}.`;
    const given_ = c.gravity_source === 'input' || c.gravity_source === 'input+image';
    e.dataset.gravitySource = given_ && p.gravitySent === 'sensors' ? 'sensors'
                            : c.gravity_source || '';
    e.dataset.lensSource = c.lens_source || '';
    e.classList.toggle('warn', c.gravity_source === 'level');
  }
  function drawPolyline(svg, h, color, selected) {
    const g = el('svg:g', {class: selected ? 'hyp selected' : 'hyp', 'data-rank': h.rank});
    for (let i = 0; i + 1 < h.points.length; i++) {
      const [a, b] = [h.points[i], h.points[i + 1]];
      const kind = h.kinds[i] || 'wall';
      const attrs = {x1: a[0], y1: a[1], x2: b[0], y2: b[1], 'vector-effect': 'non-scaling-stroke',
                     class: `seg ${kind}`};
      if (selected) g.append(el('svg:line', {...attrs, class: 'halo'}));
      const line = el('svg:line', attrs);
      line.setAttribute('stroke', color);
      g.append(line);
    }
    const mid = h.points[Math.floor(h.points.length / 2)];
    const t = el('svg:text', {x: mid[0], y: Math.max(12, mid[1] - 6), class: 'hyp-label'}, String(h.rank));
    t.setAttribute('fill', color);
    g.append(t);
    svg.append(g);
  }
  function drawPoints(svg, p) {
    const r = Math.max(p.width, p.height) / 110;
    p.points.forEach(([u, v], i) => {
      if (i > 0) {
        const [u0, v0] = p.points[i - 1];
        svg.append(el('svg:line', {x1: u0, y1: v0, x2: u, y2: v, class: 'tape',
                                   'vector-effect': 'non-scaling-stroke'}));
      }
      const pt = p.reply && p.reply.points[i];
      svg.append(el('svg:circle', {cx: u, cy: v, r, class: `pt ${pt ? pt.surface : 'pending'}`}));
      svg.append(el('svg:text', {x: u + 1.3 * r, y: v - 1.3 * r, class: 'pt-label'}, String(i + 1)));
    });
  }
  function renderPoints(p) {
    const reply = p.reply;
    $('points').replaceChildren(...p.points.map(([u, v], i) => {
      const pt = reply && reply.points[i];
      const li = el('li', {'data-u': u, 'data-v': v});
      if (!pt) { li.textContent = `pixel (${u}, ${v}) — measuring…`; return li; }
      li.dataset.surface = pt.surface;
      if (pt.error) { li.textContent = `pixel (${u}, ${v}): ${pt.error}`; li.className = 'bad'; return li; }
      const [x, y, z] = pt.xyz;
      Object.assign(li.dataset, {x: x, y: y, z: z});
      const unit = reply.metric ? (state.units === 'm' ? 'm' : 'ft') : 'camera heights';
      li.textContent = `${pt.surface} · x ${fmtCoord(x)} y ${fmtCoord(y)} z ${fmtCoord(z)} ${unit} · ` +
                       `${fmtLen(Math.hypot(x, y, z), 2)} from the camera${fmtSigma(pt.sigma_m)}`;
      return li;
    }));
    $('distances').replaceChildren(...(reply ? reply.distances : []).map((d) => {
      const li = el('li', {'data-a': d.a, 'data-b': d.b});
      if (d.error || d.distance_m === null) {
        li.textContent = `${d.a + 1} → ${d.b + 1}: ${d.error || 'no distance'}`;
        li.className = 'bad';
        return li;
      }
      li.dataset.distanceM = d.distance_m;
      li.append(`${d.a + 1} → ${d.b + 1}: `, el('b', {class: 'dist'}, reply.metric ? fmtLen(d.distance_m)
                : `${d.distance_m.toFixed(3)} camera heights`), fmtSigma(d.sigma_m));
      return li;
    }));
  }

  // ------------------------------------------------------------------ motion + floor map
  function posesKnown() {
    const out = new Map([[0, {index: 0, x_m: 0, z_m: 0, yaw_rad: 0}]]);
    if (state.trajectory) for (const q of state.trajectory) out.set(q.index, q);
    for (const [n, q] of state.poses) out.set(n, q);
    // chain motions where no pose came (a -> b with a known)
    const ms = [...state.motions.values()].filter((m) => !m.error).sort((a, b) => a.b - b.b);
    for (const m of ms) {
      if (out.has(m.b) || !out.has(m.a)) continue;
      const a = out.get(m.a), c = Math.cos(a.yaw_rad), s = Math.sin(a.yaw_rad);
      out.set(m.b, {index: m.b, x_m: a.x_m + c * m.x_m + s * m.z_m,
                    z_m: a.z_m - s * m.x_m + c * m.z_m, yaw_rad: a.yaw_rad + m.yaw_rad});
    }
    return out;
  }
  function renderMotion() {
    const sec = $('motion');
    const any = state.motions.size || state.poses.size || state.trajectory;
    if (!any && state.photos.length < 2) { sec.hidden = true; return; }
    sec.hidden = false;
    const text = $('motion-text');
    const ms = [...state.motions.values()].sort((a, b) => a.b - b.b || a.a - b.a);
    text.replaceChildren();
    if (!ms.length) {
      text.textContent = state.services.includes('odometry')
        ? 'Estimating how you moved between the photos…'
        : 'This server runs no odometry service, so the motion between photos is not estimated.';
    }
    for (const m of ms) {
      const line = el('span', {class: 'motion-line', 'data-pair': `${m.a}-${m.b}`});
      if (m.error) {
        line.textContent = `Photo ${m.b + 1} vs photo ${m.a + 1}: no estimate — ${m.error}`;
        line.classList.add('bad');
      } else {
        Object.assign(line.dataset, {xM: m.x_m, zM: m.z_m, yawDeg: m.yaw_rad * DEG});
        const yaw = m.yaw_rad * DEG;
        // the evidence: feature matches, and the walls of the two photos that line up
        const why = [];
        if (m.matches) why.push(`${m.inliers} of ${m.matches} matches agree`);
        const nw = m.layout ? m.layout.walls : 0;
        if (nw) why.push(`${nw} wall${nw > 1 ? 's' : ''} of the two photos line up`);
        line.textContent = `Photo ${m.b + 1} was taken ${fmtLen(Math.abs(m.x_m), 2)} ` +
          `${m.x_m >= 0 ? 'right' : 'left'} and ${fmtLen(Math.abs(m.z_m), 2)} ` +
          `${m.z_m >= 0 ? 'ahead' : 'behind'} of photo ${m.a + 1}, turned ` +
          `${Math.abs(yaw).toFixed(1)}° ${yaw >= 0 ? 'right' : 'left'}` +
          (why.length ? ` (${why.join('; ')}).` : '.');
        const na = (m.alternatives || []).length;
        if (na) {   // a symmetric room: say so rather than look sure
          line.textContent += ` Ambiguous: the room looks alike from ${na} other ` +
            `place${na > 1 ? 's' : ''}; a photo that shows a door or a corner decides.`;
          line.classList.add('warn');
        }
      }
      text.append(line);
    }
    const poses = posesKnown();
    $('floor-map').hidden = poses.size < 2;
    drawMap(poses);
  }
  function drawMap(poses) {
    const svg = $('floor-map');
    const pts = [...poses.values()].sort((a, b) => a.index - b.index);
    // each photo's walls registered in photo 1's frame by its pose: R(yaw) p + (x, z)
    const walls = [];
    for (const q of pts) {
      const p = photoAt(q.index), c = Math.cos(q.yaw_rad), s = Math.sin(q.yaw_rad);
      for (const w of (p && p.walls) || []) {
        walls.push({index: q.index, ends: w.map(([x, z]) => [q.x_m + c * x + s * z, q.z_m - s * x + c * z])});
      }
    }
    let minX = -1, maxX = 1, minZ = -1, maxZ = 1;
    for (const q of pts) {
      minX = Math.min(minX, q.x_m - 1); maxX = Math.max(maxX, q.x_m + 1);
      minZ = Math.min(minZ, q.z_m - 1); maxZ = Math.max(maxZ, q.z_m + 1.5);
    }
    for (const w of walls) {
      for (const [x, z] of w.ends) {
        minX = Math.min(minX, x - 0.3); maxX = Math.max(maxX, x + 0.3);
        minZ = Math.min(minZ, z - 0.3); maxZ = Math.max(maxZ, z + 0.3);
      }
    }
    const side = Math.max(maxX - minX, maxZ - minZ);   // square, like the element
    minX -= (side - (maxX - minX)) / 2; maxX = minX + side;
    minZ -= (side - (maxZ - minZ)) / 2; maxZ = minZ + side;
    const w = side, h = side;
    // map: x to the right, forward (z) up: (X, Y) = (x, -z)
    svg.setAttribute('viewBox', `${minX} ${-maxZ} ${w} ${h}`);
    svg.replaceChildren();
    svg.dataset.poses = pts.length;
    const grid = el('svg:g', {class: 'grid'});
    for (let x = Math.ceil(minX); x <= maxX; x++) {
      grid.append(el('svg:line', {x1: x, y1: -maxZ, x2: x, y2: -minZ, 'vector-effect': 'non-scaling-stroke'}));
    }
    for (let z = Math.ceil(minZ); z <= maxZ; z++) {
      grid.append(el('svg:line', {x1: minX, y1: -z, x2: maxX, y2: -z, 'vector-effect': 'non-scaling-stroke'}));
    }
    svg.append(grid);
    svg.append(el('svg:text', {x: minX + 0.1, y: -minZ - 0.12, class: 'map-note'}, 'grid: 1 m'));
    svg.dataset.walls = walls.length;
    for (const w of walls) {
      svg.append(el('svg:line', {x1: w.ends[0][0], y1: -w.ends[0][1], x2: w.ends[1][0], y2: -w.ends[1][1],
                                 class: `wall wall-${w.index % 4}`, 'data-index': w.index,
                                 'vector-effect': 'non-scaling-stroke'}));
    }
    if (pts.length > 1) {
      svg.append(el('svg:polyline', {points: pts.map((q) => `${q.x_m},${-q.z_m}`).join(' '),
                                     class: 'path', 'vector-effect': 'non-scaling-stroke'}));
    }
    for (const q of pts) {
      const s = Math.sin(q.yaw_rad), c = Math.cos(q.yaw_rad);
      const tip = [q.x_m + 0.45 * s, -(q.z_m + 0.45 * c)];
      const l = [q.x_m - 0.18 * c, -(q.z_m - 0.18 * -s)], r = [q.x_m + 0.18 * c, -(q.z_m + 0.18 * -s)];
      const g = el('svg:g', {class: 'cam', 'data-index': q.index});
      g.append(el('svg:polygon', {points: `${tip.join(',')} ${l.join(',')} ${r.join(',')}`}));
      g.append(el('svg:text', {x: q.x_m + 0.2, y: -q.z_m + 0.22, class: 'cam-label'}, String(q.index + 1)));
      svg.append(g);
    }
  }

  // ------------------------------------------------------------------ sensors + camera
  function pushSample(g, source) {
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
  function currentGravity() {
    const s = state.sensors.samples;
    if (!s.length) return null;
    const m = [0, 0, 0];
    for (const q of s) for (let i = 0; i < 3; i++) m[i] += q.g[i];
    return normalize(m);
  }
  function rotation(live = false) {
    const sel = $('orientation').value;
    if (sel !== 'auto') return Number(sel);
    if (live) {
      const a = (screen.orientation && screen.orientation.angle) ?? window.orientation ?? 0;
      return ((a % 360) + 360) % 360;
    }
    const g = currentGravity();
    return g ? autoRotation(g) : 0;
  }
  function sensorsNeedAsking() {
    return [window.DeviceOrientationEvent, window.DeviceMotionEvent]
      .some((cls) => cls && typeof cls.requestPermission === 'function');
  }
  async function startSensors(quiet = false) {
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
  function fillGravity(live) {
    const g = currentGravity();
    if (!g) { notify('No phone tilt yet: turn on the motion sensors.', 'warn', 'SENSORS'); return false; }
    const c = deviceToCamera(g, rotation(live));
    ['gx', 'gy', 'gz'].forEach((id, i) => { $(id).value = c[i].toFixed(4); });
    state.sensors.filled = ['gx', 'gy', 'gz'].map((id) => $(id).value);   // from the sensors
    return true;
  }
  async function startLive() {
    try {
      const stream = await navigator.mediaDevices.getUserMedia(
        {video: {facingMode: {ideal: 'environment'}, width: {ideal: 1920}, height: {ideal: 1440}}, audio: false});
      $('live-video').srcObject = stream;
      $('live').hidden = false;
    } catch (e) {
      notify(`The camera could not be opened: ${e.message}. Use “Take photo” instead.`, 'warn', 'CAMERA');
    }
  }
  function stopLive() {
    const v = $('live-video');
    if (v.srcObject) v.srcObject.getTracks().forEach((t) => t.stop());
    v.srcObject = null;
    $('live').hidden = true;
  }
  function shutter() {
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
  function lensFields() {
    const k = $('lens').value;
    document.querySelectorAll('.lens-fields').forEach((d) => { d.hidden = d.dataset.lens !== k; });
  }
  function init() {
    for (const id of ['camera-input', 'file-input']) {
      $(id).addEventListener('change', (e) => {
        const f = e.target.files && e.target.files[0];
        e.target.value = '';
        upload(f);
      });
    }
    $('lens').addEventListener('change', lensFields);
    lensFields();
    $('stage').addEventListener('click', onTap);
    $('show-all').addEventListener('change', render);
    $('clear-btn').addEventListener('click', () => {
      const p = photoAt(state.current);
      if (p) { p.points = []; p.reply = null; render(); }
    });
    $('units-btn').addEventListener('click', () => {
      state.units = state.units === 'm' ? 'ft' : 'm';
      $('units-btn').textContent = state.units === 'm' ? 'Show feet' : 'Show metres';
      $('units-btn').setAttribute('aria-pressed', String(state.units === 'ft'));
      render(); renderMotion();
      if (state.plan && window.FindMePlan) FindMePlan.render(state.plan, state.units);
    });
    $('height').addEventListener('change', () => {  // a new height re-builds the scene
      const p = photoAt(state.current);
      let h = null;
      try { h = heightFromForm(); } catch (e) { notify(e.message, 'error', 'FORM'); return; }
      if (p && p.hyps && p.rank && h !== null && Math.abs(h - (p.height_m || 0)) > 1e-9) selectRank(p.rank);
    });
    $('sensors-btn').addEventListener('click', () => startSensors(false));
    $('tilt-btn').addEventListener('click', () => fillGravity(false));
    $('gravity-clear-btn').addEventListener('click', () => ['gx', 'gy', 'gz'].forEach((id) => { $(id).value = ''; }));
    $('new-session-btn').addEventListener('click', () => location.reload());
    if (window.isSecureContext && navigator.mediaDevices && navigator.mediaDevices.getUserMedia) {
      $('live-btn').hidden = false;
      $('live-btn').addEventListener('click', startLive);
      $('shutter-btn').addEventListener('click', shutter);
      $('live-close-btn').addEventListener('click', stopLive);
    }
    if (window.isSecureContext && !sensorsNeedAsking() &&
        (window.DeviceOrientationEvent || window.DeviceMotionEvent)) startSensors(true);
    connect();
  }

  // for tests and the curious: the pure conversions and the state
  window.FindMe = {deviceGravityFromOrientation, deviceGravityFromMotion, deviceToCamera,
                   autoRotation, currentGravity, rotation, state, send, handle};
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', init);
  else init();
})();
