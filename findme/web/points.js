/* Find Me phone client: the points tapped on a photo (ES module): the surface the user says
 * they tap ("You tap: as the boundary says | floor | wall | top of something"), the measure
 * requests, the dots on the photo and the list of points and distances.
 *
 * A photo's points are p.points ([u, v] pixels, in tap order) and, beside them,
 * p.surfaces: what the user said each one is on when tapping it (null: as the boundary
 * says, 'floor', 'wall' or 'top'); the choice in force is state.tapAs, kept while the page is
 * open.
 * A measure request carries `surfaces` only when some point has one said, so a page where
 * nothing is said asks exactly what it asked before. Said floor: the point is put on the
 * floor whatever the chosen boundary says; said wall where the boundary puts the floor: the
 * service answers no point, with what to do (shown like any other error of a point). Said
 * top: on the top of what stands on the floor line below it (a counter, a cabinet), found by
 * its front edge, with the top's height above the floor, or no point with the reason. A
 * point said floor above the chosen line comes back with a note (``MeasuredPoint.note``),
 * shown under it with the hypotheses whose line runs above it, each a button that selects it.
 */
import {$, el, fmtCoord, fmtLen, fmtSigma, hypSwatch, send, setBusy, state} from './common.js';

// ------------------------------------------------------------------ actions
export function measure(p) {
  if (!p.points.length) { p.reply = null; return; }
  p.measureId = ++state.measureSeq;
  const msg = {type: 'measure', id: p.measureId, index: p.index, pixels: p.points};
  if (p.surfaces.some(Boolean)) msg.surfaces = p.surfaces;
  if (send(msg)) setBusy('measure', 'Measuring…');
}
export function addPoint(p, u, v) {   // a tap: the point, with what the user says it is on
  p.points.push([u, v]);
  p.surfaces.push(state.tapAs);
  p.reply = null;
}
export function clearPoints(p) {
  p.points = [];
  p.surfaces = [];
  p.reply = null;
}

// ------------------------------------------------------------------ rendering
export function drawPoints(svg, p) {
  const r = Math.max(p.width, p.height) / 110;
  p.points.forEach(([u, v], i) => {
    if (i > 0) {
      const [u0, v0] = p.points[i - 1];
      svg.append(el('svg:line', {x1: u0, y1: v0, x2: u, y2: v, class: 'tape',
                                 'vector-effect': 'non-scaling-stroke'}));
    }
    const pt = p.reply && p.reply.points[i];
    const said = p.surfaces[i];   // said: a ring around the dot (its fill stays the surface's)
    if (said) svg.append(el('svg:circle', {cx: u, cy: v, r: 1.9 * r, class: 'said-ring'}));
    svg.append(el('svg:circle', {cx: u, cy: v, r, class: `pt ${pt ? pt.surface : 'pending'}` +
                                 (said ? ' said' : ''), 'data-said': said || undefined}));
    svg.append(el('svg:text', {x: u + 1.3 * r, y: v - 1.3 * r, class: 'pt-label'}, String(i + 1)));
  });
}
function rowAt(pts, u) {   // the row of a polyline ([[u, v], ...], u non-decreasing) at column u
  for (let i = 1; i < pts.length; i++) {
    const [u0, v0] = pts[i - 1], [u1, v1] = pts[i];
    if (u <= u1 && u1 > u0) return u <= u0 ? v0 : v0 + (v1 - v0) * (u - u0) / (u1 - u0);
  }
  return pts[pts.length - 1][1];
}
// the other hypotheses whose floor line runs above pixel (u, v): what the user said agrees with
function linesAbove(p, u, v) {
  return (p.hyps || []).filter((h) => h.rank !== p.rank && rowAt(h.points, u) < v)
                       .map((h) => h.rank);
}
function noteOf(p, pt, [u, v], pick) {   // the note, and the hypotheses that agree, to pick
  const div = el('div', {class: 'note'}, pt.note);
  if (pt.said !== 'floor') return div;
  const ranks = linesAbove(p, u, v);
  div.append(el('span', {class: 'agree'}, ranks.length ? 'Hypotheses whose line runs above it:'
                                                        : 'No other hypothesis runs above it.'));
  for (const r of ranks) {
    const b = el('button', {type: 'button', class: 'chip pick', 'data-rank': r});
    b.append(hypSwatch(r), document.createTextNode(String(r)));
    b.addEventListener('click', () => pick && pick(r));
    div.append(b);
  }
  return div;
}
function surfaceText(pt, said) {   // "floor", "floor (as you said)"
  if (pt.said) return `${pt.surface} (as you said)`;
  // a service that does not take what was said: say so rather than pretend
  return said ? `${pt.surface} (you said ${said}: not taken into account)` : pt.surface;
}
export function renderPoints(p, pick) {   // pick(rank): select another hypothesis
  const reply = p.reply;
  $('points').replaceChildren(...p.points.map(([u, v], i) => {
    const pt = reply && reply.points[i];
    const said = p.surfaces[i];
    const li = el('li', {'data-u': u, 'data-v': v, 'data-said': said || ''});
    const where = `pixel (${u}, ${v})${said ? `, said ${said}` : ''}`;
    if (!pt) { li.textContent = `${where} — measuring…`; return li; }
    li.dataset.surface = pt.surface;
    if (pt.error) { li.textContent = `${where}: ${pt.error}`; li.className = 'bad'; return li; }
    const [x, y, z] = pt.xyz;
    Object.assign(li.dataset, {x: x, y: y, z: z});
    const unit = reply.metric ? (state.units === 'm' ? 'm' : 'ft') : 'camera heights';
    li.textContent = `${surfaceText(pt, said)} · x ${fmtCoord(x)} y ${fmtCoord(y)} ` +
                     `z ${fmtCoord(z)} ${unit} · ` +
                     `${fmtLen(Math.hypot(x, y, z), 2)} from the camera${fmtSigma(pt.sigma_m)}`;
    if (pt.surface === 'top' && p.gravity && reply.metric) {   // how high the top is
      const [gx, gy, gz] = p.gravity, up = p.height_m - (gx * x + gy * y + gz * z);
      li.dataset.heightM = up;
      li.append(` · its top ${fmtLen(up, 2)} above the floor`);
    }
    // what the user should know of the answer (the chosen line contradicts what was said)
    if (pt.note) li.append(noteOf(p, pt, [u, v], pick));
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

// ------------------------------------------------------------------ wiring
export function initPoints() {   // "You tap": applies to the points tapped from then on
  for (const r of document.querySelectorAll('#tap-as input[name="tap-as"]')) {
    r.checked = (r.value || null) === state.tapAs;
    r.addEventListener('change', () => {
      if (r.checked) { state.tapAs = r.value || null; $('tap-as').dataset.value = r.value; }
    });
  }
}
