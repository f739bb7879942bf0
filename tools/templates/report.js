// The wipdr report page's script: plain JavaScript and SVG, no library, nothing fetched.
// Reads the data element, makes the tables sortable, draws the error CDF and the chosen
// walk, and reports any script error into #script-errors (the browser test reads it).
(function () {
  'use strict';
  const NS = 'http://www.w3.org/2000/svg';
  const R95 = 2.447746830680816; // 95 % radius of an isotropic 2D Gaussian, in sd
  const status = document.getElementById('report-status');
  const errorsBox = document.getElementById('script-errors');

  function fail(message) {
    errorsBox.textContent += message + '\n';
    status.dataset.state = 'error';
    status.textContent = 'script error (below)';
  }
  window.addEventListener('error', (e) => fail('error: ' + e.message + ' at ' + e.filename + ':' + e.lineno));
  window.addEventListener('unhandledrejection', (e) => fail('unhandled rejection: ' + e.reason));

  function el(tag, attrs, parent) {
    const node = document.createElementNS(NS, tag);
    for (const k in attrs) node.setAttribute(k, attrs[k]);
    if (parent) parent.appendChild(node);
    return node;
  }
  function clear(node) { while (node.firstChild) node.removeChild(node.firstChild); }
  function fmt(v, d) { return (v === null || v === undefined || !isFinite(v)) ? '–' : v.toFixed(d); }

  // Ticks at 1, 2 or 5 times a power of ten, about `n` of them over [0, max].
  function ticks(max, n) {
    const raw = max / n;
    const p = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw) || raw;
    const out = [];
    for (let v = 0; v <= max + 1e-9; v += step) out.push(v);
    return out;
  }

  // A line chart of series [{colour, points: [[x, y], ...], hidden}] in `svg`.
  function lineChart(svg, series, opts) {
    clear(svg);
    const W = 900, H = opts.height || 340, m = { l: 56, r: 16, t: 14, b: 42 };
    svg.setAttribute('viewBox', '0 0 ' + W + ' ' + H);
    const xmax = opts.xmax > 0 ? opts.xmax : 1, ymax = opts.ymax > 0 ? opts.ymax : 1;
    const sx = (x) => m.l + (Math.min(x, xmax) / xmax) * (W - m.l - m.r);
    const sy = (y) => H - m.b - (Math.min(y, ymax) / ymax) * (H - m.t - m.b);
    const axes = el('g', { class: 'axes' }, svg);
    for (const v of ticks(xmax, 8)) {
      el('line', { x1: sx(v), x2: sx(v), y1: sy(0), y2: sy(ymax), stroke: '#eee' }, axes);
      el('text', { x: sx(v), y: H - m.b + 16, 'text-anchor': 'middle' }, axes).textContent = +v.toFixed(3);
    }
    for (const v of ticks(ymax, 5)) {
      el('line', { x1: sx(0), x2: sx(xmax), y1: sy(v), y2: sy(v), stroke: '#eee' }, axes);
      el('text', { x: m.l - 6, y: sy(v) + 4, 'text-anchor': 'end' }, axes).textContent = +v.toFixed(3);
    }
    el('rect', { x: m.l, y: m.t, width: W - m.l - m.r, height: H - m.t - m.b, fill: 'none', stroke: '#999' }, axes);
    el('text', { x: (W + m.l) / 2, y: H - 6, 'text-anchor': 'middle' }, axes).textContent = opts.xlabel;
    el('text', { x: 14, y: (H - m.b) / 2, transform: 'rotate(-90 14 ' + (H - m.b) / 2 + ')', 'text-anchor': 'middle' }, axes).textContent = opts.ylabel;
    for (const s of series) {
      if (s.hidden || s.points.length === 0) continue;
      el('polyline', {
        class: 'series', fill: 'none', stroke: s.colour, 'stroke-width': 2,
        points: s.points.map((p) => sx(p[0]).toFixed(1) + ',' + sy(p[1]).toFixed(1)).join(' ')
      }, svg);
      if (opts.dots) {
        for (const p of s.points) el('circle', { cx: sx(p[0]).toFixed(1), cy: sy(p[1]).toFixed(1), r: 2.5, fill: s.colour }, svg);
      }
    }
    return { sx: sx, sy: sy, W: W, H: H, m: m };
  }

  // Sorting by a click on a column head: numbers by data-sort, text otherwise, empty last.
  function makeSortable(table) {
    const heads = table.tHead.rows[0].cells;
    Array.prototype.forEach.call(heads, (th, col) => {
      th.addEventListener('click', () => {
        const desc = !th.classList.contains('sorted-desc');
        Array.prototype.forEach.call(heads, (h) => h.classList.remove('sorted-asc', 'sorted-desc'));
        th.classList.add(desc ? 'sorted-desc' : 'sorted-asc');
        const body = table.tBodies[0];
        const rows = Array.prototype.slice.call(body.rows);
        const key = (r) => {
          const v = r.cells[col].dataset.sort;
          if (v === undefined || v === '') return null;
          return isNaN(+v) ? v : +v;
        };
        rows.sort((a, b) => {
          const ka = key(a), kb = key(b);
          if (ka === null || kb === null) return (ka === null) - (kb === null); // empty last
          const c = typeof ka === 'number' && typeof kb === 'number' ? ka - kb : String(ka).localeCompare(String(kb));
          return desc ? -c : c;
        });
        for (const r of rows) body.appendChild(r);
      });
    });
  }

  function main() {
    const data = JSON.parse(document.getElementById('report-data').textContent);
    const schemes = data.schemes, palette = data.palette;
    const colour = (s) => palette[s % palette.length];
    const shown = schemes.map(() => true);
    let chosen = null;

    document.querySelectorAll('table.sortable').forEach(makeSortable);
    // Text headers (floor, walk ids) sort as text: give their cells the text as key.
    document.querySelectorAll('td[data-sort=""]').forEach((td) => {
      if (td.textContent !== '–') td.dataset.sort = td.textContent;
    });

    // ---- error CDF -------------------------------------------------------------------
    const pooled = schemes.map((_, s) => {
      const e = [];
      for (const w of data.walks) {
        const r = w.results[s];
        if (r) for (const p of r.errors) if (p[1] !== null && isFinite(p[1])) e.push(p[1]);
      }
      return e.sort((a, b) => a - b);
    });
    let cdfMax = 1;
    for (const e of pooled) if (e.length) cdfMax = Math.max(cdfMax, e[Math.floor(e.length * 0.95)] * 1.3);
    function drawCdf() {
      lineChart(document.getElementById('cdf-svg'), pooled.map((e, s) => {
        // At most 500 points per curve: the quantiles at k / 500.
        const n = e.length, step = Math.max(1, Math.floor(n / 500)), pts = [];
        for (let k = 0; k < n; k += step) pts.push([e[k], (k + 1) / n]);
        if (n) pts.push([e[n - 1], 1]);
        return { colour: colour(s), points: pts, hidden: !shown[s] };
      }), { xmax: cdfMax, ymax: 1, xlabel: 'error (m)', ylabel: 'fraction of waypoints' });
    }

    // ---- the chosen walk -------------------------------------------------------------
    const svg = document.getElementById('walk-svg');
    const slider = document.getElementById('slider');
    const wallPaths = {};
    function wallPath(floor, plan) {
      if (!(floor in wallPaths)) {
        wallPaths[floor] = plan.walls.map((w) =>
          'M' + w[0] + ' ' + (plan.height - w[1]) + 'L' + w[2] + ' ' + (plan.height - w[3])).join('');
      }
      return wallPaths[floor];
    }
    // The window of the PNG trajectory plots: truth and fixes with a 10 m margin, at least
    // 50 m a side, inside the floor.
    function windowOf(lo, hi, extent) {
      const want = Math.min(50, extent);
      if (hi - lo < want) { const c = (lo + hi) / 2; lo = c - want / 2; hi = c + want / 2; }
      if (lo < 0) { hi -= lo; lo = 0; }
      if (hi > extent) { lo -= hi - extent; hi = extent; }
      return [Math.max(lo, 0), Math.min(hi, extent)];
    }
    // The latest track point at or before t (the scored estimate; the drawn track keeps it).
    function at(track, t) {
      let lo = 0, hi = track.length - 1, best = -1;
      while (lo <= hi) { const mid = (lo + hi) >> 1; if (track[mid][0] <= t) { best = mid; lo = mid + 1; } else hi = mid - 1; }
      return best < 0 ? null : track[best];
    }

    function drawWalk(index) {
      const w = data.walks[index];
      chosen = index;
      document.querySelectorAll('#walk-table tr.walk-row').forEach((r) =>
        r.classList.toggle('chosen', +r.dataset.index === index));
      document.getElementById('walk-title').textContent = w.floor + ' · ' + w.walk + ' (fold ' + w.fold + ')';
      clear(svg);
      const plan = data.plans[w.floor];
      const note = document.getElementById('walk-note');
      if (!data.has_tracks || !plan) {
        note.textContent = 'This results file has no drawing data: write it with `wipdr eval --json FILE --json-tracks` (or use `wipdr eval --report`) to see the tracks.';
      } else {
        note.textContent = 'North up; black: truth waypoints; grey crosses: Wi-Fi fixes; circles at the slider\'s waypoint: each estimate\'s 95 % radius where the scheme has one. Tracks drawn downsampled (' + data.drawing.tolerance_m + ' m tolerance; the estimates scored at waypoints are kept).';
      }
      const H = plan ? plan.height : 0;
      let lo = [Infinity, Infinity], hi = [-Infinity, -Infinity];
      for (const p of w.truth.concat(w.fixes)) {
        lo = [Math.min(lo[0], p[1]), Math.min(lo[1], p[2])];
        hi = [Math.max(hi[0], p[1]), Math.max(hi[1], p[2])];
      }
      if (plan) {
        let xw = windowOf(lo[0] - 10, hi[0] + 10, plan.width), yw = windowOf(lo[1] - 10, hi[1] + 10, plan.height);
        if (!(xw[1] > xw[0] && yw[1] > yw[0])) { xw = [0, plan.width]; yw = [0, plan.height]; }
        svg.setAttribute('viewBox', xw[0] + ' ' + (H - yw[1]) + ' ' + (xw[1] - xw[0]) + ' ' + (yw[1] - yw[0]));
        svg.dataset.size = Math.max(xw[1] - xw[0], yw[1] - yw[0]);
        // Only an embedded PNG (what `wipdr eval` writes) is drawn as the floor image.
        if (typeof plan.image === 'string' && plan.image.startsWith('data:image/png;base64,')) {
          el('image', { href: plan.image, x: 0, y: 0, width: plan.width, height: plan.height, preserveAspectRatio: 'none' }, svg);
        } else {
          el('rect', { x: 0, y: 0, width: plan.width, height: plan.height, fill: '#f5f5f0' }, svg);
        }
        el('path', { d: wallPath(w.floor, plan), fill: 'none', stroke: typeof plan.image === 'string' ? 'rgba(60,60,60,0.45)' : '#6e645a', 'stroke-width': 1, 'vector-effect': 'non-scaling-stroke', class: 'walls' }, svg);
      }
      const size = +svg.dataset.size || 50, dot = size / 220;
      const y = (v) => H - v;
      const fixes = el('g', { class: 'fixes' }, svg);
      for (const f of w.fixes) {
        el('path', { d: 'M' + (f[1] - dot) + ' ' + (y(f[2]) - dot) + 'l' + 2 * dot + ' ' + 2 * dot + 'm0 ' + (-2 * dot) + 'l' + (-2 * dot) + ' ' + 2 * dot, stroke: '#777', 'stroke-width': 1.2, 'vector-effect': 'non-scaling-stroke', class: 'fix' }, fixes);
      }
      const tracks = el('g', { class: 'tracks' }, svg);
      w.results.forEach((r, s) => {
        if (!r || !r.track || r.track.length === 0) return;
        el('polyline', {
          class: 'track', 'data-scheme': schemes[s], fill: 'none', stroke: colour(s), 'stroke-width': 2,
          'stroke-opacity': 0.9, 'vector-effect': 'non-scaling-stroke', visibility: shown[s] ? 'visible' : 'hidden',
          points: r.track.map((p) => p[1] + ',' + y(p[2])).join(' ')
        }, tracks);
      });
      const truth = el('g', { class: 'truth' }, svg);
      if (w.truth.length) {
        el('polyline', { points: w.truth.map((p) => p[1] + ',' + y(p[2])).join(' '), fill: 'none', stroke: '#000', 'stroke-width': 2.5, 'vector-effect': 'non-scaling-stroke' }, truth);
      }
      w.truth.forEach((p, k) => {
        const c = el('circle', { cx: p[1], cy: y(p[2]), r: dot * 1.2, fill: '#000', class: 'waypoint' }, truth);
        c.addEventListener('mouseenter', () => { slider.value = k; cursor(k); });
      });
      el('g', { id: 'cursor' }, svg);
      slider.max = Math.max(0, w.truth.length - 1);
      // Start at the first waypoint some scheme was scored at (earlier ones are skipped).
      const first = Math.max(0, w.truth.findIndex((p) => w.results.some((r) => scoredAt(r, p[0]))));
      slider.value = first;
      drawErrors(w);
      cursor(first);
      status.dataset.tracksDrawn = svg.querySelectorAll('polyline.track').length;
    }

    // The error of scheme s's result r at the waypoint of time t, with its sd, or null.
    function scoredAt(r, t) {
      if (!r) return null;
      const k = r.errors.findIndex((e) => e[0] === t);
      if (k < 0) return null;
      return { error: r.errors[k][1], floor: r.errors[k][2], sd: r.sd_m ? r.sd_m[k] : null };
    }

    function cursor(k) {
      const w = data.walks[chosen];
      const g = document.getElementById('cursor');
      if (!g) return;
      clear(g);
      const readout = document.getElementById('readout');
      clear(readout);
      const label = document.getElementById('slider-label');
      if (!w.truth.length) {
        label.textContent = 'this walk has no waypoints in the file';
        return;
      }
      const p = w.truth[k], t0 = w.truth[0][0];
      const H = data.plans[w.floor] ? data.plans[w.floor].height : 0;
      const size = +svg.dataset.size || 50, dot = size / 220;
      label.textContent = (k + 1) + ' of ' + w.truth.length + ', ' + ((p[0] - t0) / 1000).toFixed(1) + ' s';
      const table = document.createElement('table');
      table.innerHTML = '<thead><tr><th>scheme</th><th>error (m)</th><th>sd (m)</th><th>95 % radius (m)</th><th>estimate (x, y)</th></tr></thead>';
      const body = document.createElement('tbody');
      table.appendChild(body);
      w.results.forEach((r, s) => {
        const sc = scoredAt(r, p[0]);
        const est = r && r.track ? at(r.track, p[0]) : null;
        if (est && shown[s]) {
          el('line', { x1: p[1], y1: H - p[2], x2: est[1], y2: H - est[2], stroke: colour(s), 'stroke-width': 1, 'stroke-dasharray': '3 2', 'vector-effect': 'non-scaling-stroke' }, g);
          if (est[3] !== null && est[3] !== undefined) {
            el('circle', { cx: est[1], cy: H - est[2], r: R95 * est[3], fill: colour(s), 'fill-opacity': 0.04, stroke: colour(s), 'stroke-width': 1, 'vector-effect': 'non-scaling-stroke', class: 'radius' }, g);
          }
          el('circle', { cx: est[1], cy: H - est[2], r: dot * 1.6, fill: colour(s), stroke: '#fff', 'stroke-width': 1, 'vector-effect': 'non-scaling-stroke', class: 'estimate' }, g);
        }
        const tr = document.createElement('tr');
        if (!shown[s]) tr.className = 'hidden-scheme';
        const sd = sc ? sc.sd : (est ? est[3] : null);
        // Built as nodes and text, never as markup: scheme names come from the results file.
        const name = document.createElement('td');
        const swatch = document.createElement('span');
        swatch.className = 'swatch';
        swatch.style.background = colour(s);
        name.appendChild(swatch);
        name.appendChild(document.createTextNode(String(schemes[s])));
        tr.appendChild(name);
        for (const text of [
          sc ? fmt(sc.error, 2) + (sc.floor ? ' (floor ' + (sc.floor > 0 ? '+' : '') + sc.floor + ')' : '') : 'not scored',
          fmt(sd, 2), sd === null || sd === undefined ? '–' : fmt(R95 * sd, 2),
          est ? fmt(est[1], 1) + ', ' + fmt(est[2], 1) : '–'
        ]) {
          const td = document.createElement('td');
          td.textContent = text;
          tr.appendChild(td);
        }
        body.appendChild(tr);
      });
      readout.appendChild(table);
      el('circle', { cx: p[1], cy: H - p[2], r: dot * 2.6, fill: 'none', stroke: '#000', 'stroke-width': 2, 'vector-effect': 'non-scaling-stroke' }, g);
      const ex = document.getElementById('error-cursor');
      if (ex && errorChart) {
        const x = errorChart.sx((p[0] - t0) / 1000);
        ex.setAttribute('x1', x); ex.setAttribute('x2', x);
      }
    }

    let errorChart = null;
    function drawErrors(w) {
      const t0 = w.truth.length ? w.truth[0][0] : 0;
      let tmax = 1, emax = 1;
      const series = w.results.map((r, s) => {
        const pts = r ? r.errors.filter((e) => e[1] !== null).map((e) => [(e[0] - t0) / 1000, e[1]]) : [];
        for (const p of pts) { tmax = Math.max(tmax, p[0]); if (shown[s]) emax = Math.max(emax, p[1]); }
        return { colour: colour(s), points: pts, hidden: !shown[s] };
      });
      const chart = document.getElementById('error-svg');
      errorChart = lineChart(chart, series, { xmax: tmax * 1.02, ymax: emax * 1.05, height: 300, dots: true, xlabel: 'time since the first waypoint (s)', ylabel: 'error (m)' });
      el('line', { id: 'error-cursor', x1: 0, x2: 0, y1: errorChart.m.t, y2: errorChart.H - errorChart.m.b, stroke: '#000', 'stroke-dasharray': '4 3' }, chart);
    }

    document.querySelectorAll('#scheme-toggles input').forEach((box) => {
      box.addEventListener('change', () => {
        shown[+box.dataset.scheme] = box.checked;
        drawCdf();
        if (chosen !== null) { const k = +slider.value; drawWalk(chosen); slider.value = k; cursor(k); }
      });
    });
    slider.addEventListener('input', () => cursor(+slider.value));
    document.querySelectorAll('#walk-table tr.walk-row').forEach((row) =>
      row.addEventListener('click', () => drawWalk(+row.dataset.index)));

    drawCdf();
    const rows = document.querySelectorAll('#walk-table tr.walk-row');
    status.dataset.walksListed = rows.length;
    if (rows.length) drawWalk(+rows[0].dataset.index);
  }

  try {
    main();
    if (status.dataset.state !== 'error') {
      status.dataset.state = 'ready';
      status.textContent = '';
    }
  } catch (e) {
    fail('error: ' + (e && e.stack ? e.stack : String(e)));
  }
})();
