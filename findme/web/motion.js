/* Find Me phone client: where you moved (ES module): each motion between two photos in
 * words, with its evidence (feature matches, walls that line up) and its ambiguity, and a
 * map of the photos' positions with each photo's walls, in photo 1's level frame (x to the
 * right, forward up; the odometry's poses and trajectory, else the motions chained).
 */
import {$, DEG, clearBusy, el, fmtLen, fmtSigma, notify, photoAt, setBusy, state} from './common.js';

export function posesKnown() {
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
export function renderMotion() {
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
      // each number with its 1-sigma, as the points and distances are said
      const sy = m.sigma_yaw_rad == null ? '' : ` ± ${(m.sigma_yaw_rad * DEG).toFixed(1)}°`;
      line.textContent = `Photo ${m.b + 1} was taken ${fmtLen(Math.abs(m.x_m), 2)}` +
        `${fmtSigma(m.sigma_x_m)} ${m.x_m >= 0 ? 'right' : 'left'} and ` +
        `${fmtLen(Math.abs(m.z_m), 2)}${fmtSigma(m.sigma_z_m)} ` +
        `${m.z_m >= 0 ? 'ahead' : 'behind'} of photo ${m.a + 1}, turned ` +
        `${Math.abs(yaw).toFixed(1)}°${sy} ${yaw >= 0 ? 'right' : 'left'}` +
        (why.length ? ` (${why.join('; ')}).` : '.');
      // the other motions the evidence allows: at another distance along the same way (the
      // same turn and direction of travel, within 3°: a wall or floor line one photo misread)
      // or at another place (a symmetric room); say so rather than look sure
      const alts = m.alternatives || [];
      const same = (a, b) => Math.abs(Math.atan2(Math.sin(a - b), Math.cos(a - b))) < 3 / DEG;
      const along = alts.filter((a) => same(a.yaw_rad, m.yaw_rad) &&
        same(Math.atan2(a.x_m, a.z_m), Math.atan2(m.x_m, m.z_m)));
      const na = alts.length - along.length;
      if (along.length) {
        line.textContent += ` The distance is uncertain: the photos also allow ` +
          `${along.map((a) => fmtLen(Math.hypot(a.x_m, a.z_m), 2)).join(' or ')} apart ` +
          `instead of ${fmtLen(Math.hypot(m.x_m, m.z_m), 2)}; a photo that shows where the ` +
          `floor meets the walls decides.`;
      }
      if (na) {
        line.textContent += ` Ambiguous: the room looks alike from ${na} other ` +
          `place${na > 1 ? 's' : ''}; a photo that shows a door or a corner decides.`;
      }
      if (alts.length) line.classList.add('warn');
    }
    text.append(line);
  }
  const poses = posesKnown();
  $('floor-map').hidden = poses.size < 2;
  drawMap(poses);
}
export function drawMap(poses) {
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
export function expectMotion(n) {
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