/* Find Me phone client: the room's floor plan, as the mapper publishes it (findme.v1.Plan,
 * sent by the gateway as {"type": "plan", ...}: services/web/page_output.py).
 *
 * Seen from above: x to the right, forward (z of the first photo) UP, so the SVG draws
 * (x, -z) in metres. The outline is counter-clockwise seen from above; a wall's length label
 * sits just outside it (to the right of a -> b). Walls not seen ("missing": the outline is
 * closed there only because nothing was seen beyond) are dashed, openings orange; each
 * placed photo is a numbered triangle pointing where it looked. Lengths in metres or feet
 * and inches (the page's unit toggle); "h" (camera heights) when the plan is not metric.
 *
 * FindMePlan.render(plan, units) fills the #plan section; FindMePlan.draw(svg, plan, units)
 * only the drawing.
 */
'use strict';
window.FindMePlan = (function () {
  const SVG = 'http://www.w3.org/2000/svg';
  const FT = 0.3048, IN = 0.0254;

  function el(tag, attrs = {}, text) {
    const e = tag.startsWith('svg:') ? document.createElementNS(SVG, tag.slice(4))
                                     : document.createElement(tag);
    for (const [k, v] of Object.entries(attrs)) if (v !== undefined && v !== null) e.setAttribute(k, v);
    if (text !== undefined) e.textContent = text;
    return e;
  }
  function lengthText(m, units, metric = true) {
    if (!metric) return `${m.toFixed(2)} h`;
    if (units !== 'ft') return `${m.toFixed(2)} m`;
    const inches = Math.round(m / IN);
    return `${Math.floor(inches / 12)}′ ${inches % 12}″`;
  }
  function areaText(a, units, metric = true) {
    if (!metric) return `${a.toFixed(2)} h²`;
    return units === 'ft' ? `${(a / (FT * FT)).toFixed(0)} ft²` : `${a.toFixed(1)} m²`;
  }
  const placed = (plan) => plan.poses.filter((q) => q.status === 'placed');

  function draw(svg, plan, units) {
    svg.replaceChildren();
    const pts = [...plan.polygon, ...placed(plan).map((q) => [q.x_m, q.z_m])];
    if (!pts.length) return;
    let minX = Infinity, maxX = -Infinity, minZ = Infinity, maxZ = -Infinity;
    for (const [x, z] of pts) {
      minX = Math.min(minX, x); maxX = Math.max(maxX, x); minZ = Math.min(minZ, z); maxZ = Math.max(maxZ, z);
    }
    const pad = 0.12 * Math.max(maxX - minX, maxZ - minZ, 1) + 0.4;
    minX -= pad; maxX += pad; minZ -= pad; maxZ += pad;
    const side = Math.max(maxX - minX, maxZ - minZ);   // square, like the element
    minX -= (side - (maxX - minX)) / 2; minZ -= (side - (maxZ - minZ)) / 2;
    maxZ = minZ + side;
    svg.setAttribute('viewBox', `${minX} ${-maxZ} ${side} ${side}`);
    const fs = side * 0.04;     // text size in metres of the drawing
    svg.dataset.walls = plan.walls.length;
    svg.dataset.closed = String(plan.closed);
    if (plan.polygon.length >= 3) {
      svg.append(el('svg:polygon', {class: 'floor', points: plan.polygon.map(([x, z]) => `${x},${-z}`).join(' ')}));
    }
    const labels = el('svg:g', {class: 'labels'});
    plan.walls.forEach((w, k) => {
      const line = el('svg:line', {x1: w.a[0], y1: -w.a[1], x2: w.b[0], y2: -w.b[1],
                                   class: `wall ${w.kind}`, 'data-index': k, 'data-kind': w.kind,
                                   'data-length-m': w.length_m, 'vector-effect': 'non-scaling-stroke'});
      svg.append(line);
      const dx = w.b[0] - w.a[0], dz = w.b[1] - w.a[1], L = Math.hypot(dx, dz) || 1;
      for (const [f, t] of w.openings) {
        svg.append(el('svg:line', {x1: w.a[0] + f * dx / L, y1: -(w.a[1] + f * dz / L),
                                   x2: w.a[0] + t * dx / L, y2: -(w.a[1] + t * dz / L),
                                   class: 'wall gap', 'vector-effect': 'non-scaling-stroke'}));
      }
      // outside a counter-clockwise outline: right of a -> b (seen from above) = (dz, -dx)
      const off = 0.9 * fs, mx = (w.a[0] + w.b[0]) / 2 + off * dz / L, mz = (w.a[1] + w.b[1]) / 2 - off * dx / L;
      let ang = Math.atan2(-dz, dx) * 180 / Math.PI;   // along the wall on screen, kept upright
      if (ang > 90) ang -= 180; else if (ang < -90) ang += 180;
      labels.append(el('svg:text', {x: mx, y: -mz, class: `wall-label ${w.kind}`, 'data-index': k,
                                    'data-length-m': w.length_m, 'font-size': fs,
                                    'text-anchor': 'middle', 'dominant-baseline': 'middle',
                                    transform: `rotate(${ang.toFixed(2)} ${mx} ${-mz})`},
                                lengthText(w.length_m, units, plan.metric) + (w.kind === 'missing' ? '?' : '')));
    });
    svg.append(labels);
    (plan.corner_sigma_m || []).forEach((s, k) => {   // where a corner may be: its 1-sigma
      if (!s || k >= plan.polygon.length) return;      // none: a corner of a wall not seen
      const [x, z] = plan.polygon[k];
      svg.append(el('svg:ellipse', {class: 'plan-corner-sigma', 'data-index': k, cx: x, cy: -z,
                                    rx: s[0], ry: s[1]}));
    });
    for (const q of placed(plan)) {
      const s = Math.sin(q.yaw_rad), c = Math.cos(q.yaw_rad), r = 0.8 * fs;
      const tip = [q.x_m + 1.8 * r * s, -(q.z_m + 1.8 * r * c)];
      const l = [q.x_m - r * c, -(q.z_m + r * s)], rt = [q.x_m + r * c, -(q.z_m - r * s)];
      const g = el('svg:g', {class: 'plan-cam', 'data-index': q.index});
      if (q.sigma_x_m > 0 || q.sigma_z_m > 0) {   // where it may be: its 1-sigma in x and z
        g.append(el('svg:ellipse', {class: 'plan-cam-sigma', cx: q.x_m, cy: -q.z_m,
                                    rx: q.sigma_x_m, ry: q.sigma_z_m}));
      }
      g.append(el('svg:polygon', {points: `${tip.join(',')} ${l.join(',')} ${rt.join(',')}`}));
      svg.append(g);
    }
    const seen = new Set();   // one number per position (photos of one spot share it)
    for (const q of placed(plan)) {
      const key = `${q.x_m.toFixed(2)},${q.z_m.toFixed(2)}`;
      const same = placed(plan).filter((p) => `${p.x_m.toFixed(2)},${p.z_m.toFixed(2)}` === key);
      if (seen.has(key)) continue;
      seen.add(key);
      const names = same.map((p) => p.index + 1);
      const text = names.length > 2 ? `${names[0]}–${names[names.length - 1]}` : names.join(',');
      svg.append(el('svg:text', {x: q.x_m + 0.9 * fs, y: -q.z_m - 0.9 * fs, class: 'plan-cam-label',
                                 'font-size': 0.8 * fs}, text));
    }
  }

  // the latest plan worth showing: one with an outline, or one whose outline was refused
  // while its photos stand placed (it says the room is not what an older outline drew); kept
  // on screen when a newer plan has neither (one more photo can leave too little agreement)
  let lastShown = null;
  function render(latest, units) {
    const sec = document.getElementById('plan');
    if (!sec) return;
    sec.hidden = false;
    sec.dataset.upTo = latest.up_to_index;
    const shows = (p) => !p.reason || placed(p).length > 0;
    if (shows(latest)) lastShown = latest;
    const plan = shows(latest) || !lastShown ? latest : lastShown;
    // an outline refused (the photos disagree about the room) still places its photos: show
    // where they were taken, not an older outline that they now contradict
    const refused = !!plan.reason && placed(plan).length > 0;
    sec.dataset.shown = plan.up_to_index;
    sec.dataset.refused = String(refused);
    const text = document.getElementById('plan-text');
    const n = plan.poses.length, k = placed(plan).length;
    if (refused) {
      text.textContent = `No floor plan from ${n} photos: they disagree about the room, so its ` +
        `outline is not drawn (the server says: ${plan.reason}). Where ${k} of them were ` +
        'taken is shown.' + (plan === latest ? '' : ` With photo ${latest.up_to_index + 1} ` +
        `nothing is placed (the server says: ${latest.reason}).`);
    } else if (plan !== latest) {
      text.textContent = `With photo ${latest.up_to_index + 1} there is no outline yet (the server says: ` +
        `${latest.reason}); the plan of the first ${plan.photos} photos is shown.`;
    } else if (plan.reason) {
      text.textContent = `No floor plan yet from ${plan.photos} photo${plan.photos === 1 ? '' : 's'}: ` +
        'keep turning round where you stand, taking photos that show the floor and the foot of ' +
        `the walls (the server says: ${plan.reason}).`;
    } else {
      const missing = plan.walls.filter((w) => w.kind === 'missing').length;
      text.textContent = `${plan.walls.length} walls, floor area ${areaText(plan.area_m2, units, plan.metric)}; ` +
        `${k} of ${n} photos placed.` + (missing ? ` ${missing} wall${missing === 1 ? '' : 's'} not seen yet ` +
        '(dashed): take photos towards them.' : ' Every wall seen.') +
        (plan.metric ? '' : ' No camera height: lengths in camera heights (h).');
    }
    const svg = document.getElementById('plan-map');
    svg.toggleAttribute('hidden', !!plan.reason && !refused);   // an SVG element has no .hidden
    draw(svg, plan, units);
    const list = document.getElementById('plan-walls');
    list.replaceChildren(...plan.walls.map((w, i) => el('li', {'data-kind': w.kind, 'data-length-m': w.length_m},
      `Wall ${i + 1}: ${lengthText(w.length_m, units, plan.metric)}` +
      (w.sigma_m == null ? '' : ' ± ' + (units === 'ft' && plan.metric ? (w.sigma_m / IN).toFixed(1) + '″'
                                                                       : lengthText(w.sigma_m, 'm', plan.metric))) +
      (w.kind === 'missing' ? ' — not seen: inferred, not measured' : w.kind === 'opening' ? ' — an opening' : '') +
      (w.openings.length ? ` — ${w.openings.length} door/opening${w.openings.length > 1 ? 's' : ''}` : ''))));
    const left = plan.poses.filter((q) => q.status !== 'placed' && q.reason && q.reason !== plan.reason);
    const notes = document.getElementById('plan-notes');
    notes.replaceChildren(...left.map((q) => el('li', {'data-index': q.index},
      `Photo ${q.index + 1}: ${q.reason}`)));
  }

  return {draw, render, lengthText};
})();
