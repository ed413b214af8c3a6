/* Find Me phone client: the result of a photo (ES module): its tabs, the photo with its
 * boundary hypotheses (the chosen one on top, the others on request), the hypothesis chips,
 * where its lens and gravity came from, and the taps on it (points.js holds the points, what
 * the user says they are on, their 3D position, distances and 1-sigma, asked of the
 * measurement service through the gateway).
 */
import {$, DEG, el, fmtLen, hypColor, hypSwatch, notify, photoAt, send, setBusy, state} from './common.js';
import {renderMotion} from './motion.js';
import {addPoint, clearPoints, drawPoints, initPoints, measure, renderPoints} from './points.js';
import {heightFromForm} from './settings.js';


// ------------------------------------------------------------------ actions
export function selectRank(rank) {
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
export function onTap(ev) {
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
  addPoint(p, u, v);
  render();
  if (p.sceneRank) measure(p);
}
// ------------------------------------------------------------------ rendering
export function show(n) {
  state.current = n;
  $('result').hidden = false;
  render();
  renderMotion();
}
export function render() {
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
    drawPolyline(svg, h, hypColor(h.rank), h.rank === p.rank);
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
    b.append(hypSwatch(h.rank), document.createTextNode(h.rank === 1 ? '1 (best)' : String(h.rank)));
    b.addEventListener('click', () => selectRank(h.rank));
    return b;
  }));
  chips.dataset.key = `${p.index}/${hyps.length}`;
  let status;
  if (!p.hyps) status = `Photo ${p.index + 1} (${p.width}×${p.height}): finding the floor boundary…`;
  else if (!hyps.length) status = `Photo ${p.index + 1}: no floor boundary found (${p.reason}).`;
  else if (p.notRoom) {
    status = `Photo ${p.index + 1} does not look like a room view: ${p.notRoom}. ` +
             `${hyps.length} boundary guesses; showing ${p.rank}.`;
  } else {
    status = `Photo ${p.index + 1}: ${hyps.length} boundary hypotheses; showing ` +
             `${p.rank}${p.by === 'user' ? ' (your choice)' : p.rank === 1 ? ' (best)' : ''}.`;
    if (p.sceneRank && p.sceneRank === p.rank) {
      status += p.metric ? ` Camera ${fmtLen(p.height_m, 2)} above the floor.`
                         : ' No camera height: distances are in camera heights.';
    }
  }
  $('photo-status').textContent = status;
  $('photo-status').classList.toggle('warn', Boolean(p.notRoom));
  $('photo-status').dataset.notRoomView = p.notRoom || '';
  renderSources(p);
  renderPoints(p, selectRank);
}
export function renderSources(p) {   // where the lens and gravity of this photo came from
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
export function drawPolyline(svg, h, color, selected) {
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

// ------------------------------------------------------------------ wiring
export function initResults() {
  initPoints();
  $('stage').addEventListener('click', onTap);
  $('show-all').addEventListener('change', render);
  $('clear-btn').addEventListener('click', () => {
    const p = photoAt(state.current);
    if (p) { clearPoints(p); render(); }
  });
  $('height').addEventListener('change', () => {  // a new height re-builds the scene
    const p = photoAt(state.current);
    let h = null;
    try { h = heightFromForm(); } catch (e) { notify(e.message, 'error', 'FORM'); return; }
    if (p && p.hyps && p.rank && h !== null && Math.abs(h - (p.height_m || 0)) > 1e-9) selectRank(p.rank);
  });
}
