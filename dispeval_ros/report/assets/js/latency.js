  // ---- latency against accuracy, and the delay per frame (report/latency.py builds the data)

  /* Indices of the non-dominated points in increasing x (latency_figures.front_2d): both axes
   * minimised unless higher is better; NaN points are never on it. */
  function front2d(points, xHigher, yHigher) {
    const sx = xHigher ? -1 : 1, sy = yHigher ? -1 : 1;
    const finite = [];
    points.forEach(function (p, i) {
      if (isFinite(p.x) && isFinite(p.y)) finite.push([sx * p.x, sy * p.y, i]);
    });
    finite.sort(function (a, b) { return a[0] - b[0] || a[1] - b[1] || a[2] - b[2]; });
    const chosen = [];
    let best = Infinity;
    for (const [, y, i] of finite) if (y < best) { chosen.push(i); best = y; }
    return chosen;
  }

  /* obj[key] if obj has it as its own (a method called "__proto__" is data, not the prototype). */
  function own(obj, key) {
    return Object.prototype.hasOwnProperty.call(obj, key) ? obj[key] : undefined;
  }

  /* Names of A* group 1 of the run's objectives (latency.py: the summary's per sequence) among
   * the selected methods of sequence s: the accuracy objectives built as the page builds its
   * own models' (buildObjectives: the common frames of these methods), the timing ones from
   * the sequence's values (objectives.timing_objectives), so deselecting a method regroups the
   * rest as summarize would on them. Empty without groups, or for fewer than two methods. */
  function firstGroupOf(s, block, methodIdx) {
    const info = D.raw.latency;
    if (!block.groups) return new Set();  // the models could not be made on the run's objectives
    const timed = {};
    for (const m of info.measures) timed[m.name] = m;
    const timing = info.objective_measures.filter(function (q) { return own(timed, q); });
    const built = buildObjectives({
      sequences: [D.sequences[s].name],
      methods: methodIdx.filter(function (m) { return D.seqHas[s * D.M + m]; })
        .map(function (m) { return D.methods[m]; }),
      criteria: D.criteria.filter(function (c) { return !c.overlapping; })
        .map(function (c) { return c.name; }),
      measures: info.objective_measures.filter(function (q) { return !own(timed, q); }),
      granularity: info.granularity,
    });
    const n = built.n, width = built.m + timing.length;
    if (n < 2 || !(built.common[s] || []).length || !width) return new Set();
    const matrix = new Float64Array(n * width);
    built.methods.forEach(function (method, i) {
      matrix.set(built.matrix.subarray(i * built.m, (i + 1) * built.m), i * width);
      const values = own(block.values, method) || {};
      timing.forEach(function (q, k) {
        const v = own(values, q);
        const x = v === null || v === undefined ? NaN : v;
        matrix[i * width + built.m + k] = timed[q].higher ? -x : x;
      });
    });
    return new Set(evaluateModels(built.methods, matrix, n, width).astar);
  }

  function buildLatencyView() {
    const info = D.raw.latency;
    ui.latencyPlots = el('div', { id: 'latency-plots', className: 'bars' });
    ui.latencyNote = el('p', { id: 'latency-note', className: 'muted small' });
    const children = [el('h2', { text: 'Latency against accuracy' })];
    if (info.recorded) {
      state.latencyMeasure = info.default;
      ui.latencyMeasure = el('select', { id: 'latency-measure', 'aria-label': 'latency measure' });
      for (const m of info.measures) {
        ui.latencyMeasure.appendChild(el('option', { value: m.name, text: m.label }));
      }
      ui.latencyMeasure.value = state.latencyMeasure;
      ui.latencyMeasure.addEventListener('change', function () {
        state.latencyMeasure = ui.latencyMeasure.value; render();
      });
      children.push(el('div', { className: 'plot-controls' }, [
        el('label', {}, [el('span', { text: 'x: latency measure ' }), ui.latencyMeasure]),
        el('span', { className: 'muted small', text: 'y: the measure and criterion chosen ' +
          'for the per-frame scores above' }),
      ]));
    }
    children.push(ui.latencyNote, ui.latencyPlots);
    ui.latencyView = el('section', { id: 'latency-view', className: 'view' }, children);
    return ui.latencyView;
  }

  function renderLatency(built) {
    const info = D.raw.latency;
    clear(ui.latencyPlots);
    D.latencyState = { recorded: info.recorded, sequences: {} };
    if (!info.recorded) {
      ui.latencyNote.textContent = info.not_recorded;
      return;
    }
    const q = state.plotMeasure, c = state.plotCriterion;
    const recipe = D.measures[q];
    const xm = info.measures.find(function (m) { return m.name === state.latencyMeasure; });
    const defined = applies(c, q);
    const unit = unitOf(recipe, built.methodIdx);
    const yLabel = recipe.name + (unit ? ' [' + unit + ']' : '');
    const missing = [];
    for (const s of built.seqs) {
      const name = D.sequences[s].name;
      const block = own(info.sequences, name);
      if (!block) { missing.push(name); continue; }
      const frames = built.common[s] || [];
      const methods = built.methodIdx.filter(function (m) {
        return own(block.values, D.methods[m]) !== undefined;
      });
      const ringed = firstGroupOf(s, block, built.methodIdx);
      const points = methods.map(function (m) {
        const method = D.methods[m];
        const x = block.values[method][xm.name];
        const totals = defined ? totalsOf(frames, c, m) : null;
        return {
          name: method, x: x === null ? NaN : x, y: totals ? totalMeasure(recipe, totals) : NaN,
          first: ringed.has(method),
        };
      });
      const front = front2d(points, xm.higher, !!recipe.higher);
      D.latencyState.sequences[name] = {
        x: xm.name, points: points, front: front.map(function (i) { return points[i].name; }),
      };
      ui.latencyPlots.appendChild(scatterChart(name + ' · ' + D.criteria[c].name, xm.label,
        yLabel, points, front));
      ui.latencyPlots.appendChild(delayChart(name, s, block, methods));
    }
    ui.latencyNote.textContent = 'x: ' + xm.label + ' (' + xm.text + ', over every frame the ' +
      'method delivered); y: ' + yLabel + ' of criterion ' + D.criteria[c].name +
      ' over the frames every selected method delivered. Ringed: A* group 1 of the selected ' +
      'methods over the run\'s objectives (' + info.objective_measures.join(', ') + (info.granularity === 'frame'
        ? ', per frame' : '') + '); line: the non-dominated front of these two axes.' +
      (defined ? '' : ' ' + recipe.name + ' is not defined on criterion ' + D.criteria[c].name +
        ': no y values.') +
      (info.problem ? ' No groups: ' + info.problem : '') +
      (missing.length ? ' ' + missing.join(', ') + ': ' + info.not_recorded : '');
  }

  function linear(lo, hi, a, b) {
    if (!(hi > lo)) { const pad = Math.abs(lo) * 0.1 || 1; lo -= pad; hi += pad; }
    const span = hi - lo;
    lo -= span * 0.08; hi += span * 0.08;
    const scale = function (v) { return a + (v - lo) / (hi - lo) * (b - a); };
    scale.lo = lo; scale.hi = hi;
    return scale;
  }

  function extent(values) {
    let lo = Infinity, hi = -Infinity;
    for (const v of values) if (isFinite(v)) { if (v < lo) lo = v; if (v > hi) hi = v; }
    return lo <= hi ? [lo, hi] : [0, 1];
  }

  function chartFrame(title, xLabel, yLabel, width, height, box) {
    const root = svg('svg', { width: width, height: height, viewBox: '0 0 ' + width + ' ' + height,
      class: 'latency-chart' });
    root.appendChild(svg('text', { x: 4, y: 14, class: 'chart-title' }, title));
    root.appendChild(svg('line', { x1: box.left, y1: box.top, x2: box.left, y2: box.bottom, class: 'axis' }));
    root.appendChild(svg('line', { x1: box.left, y1: box.bottom, x2: box.right, y2: box.bottom, class: 'axis' }));
    root.appendChild(svg('text', { x: (box.left + box.right) / 2, y: height - 4, class: 'tick x-label',
      'text-anchor': 'middle' }, xLabel));
    const ty = (box.top + box.bottom) / 2;
    root.appendChild(svg('text', { x: 12, y: ty, class: 'tick y-label', 'text-anchor': 'middle',
      transform: 'rotate(-90 12 ' + ty + ')' }, yLabel));
    return root;
  }

  function ticks(root, box, xs, ys, xText, yText) {
    for (const [v, text] of xText) {
      root.appendChild(svg('text', { x: xs(v), y: box.bottom + 14, class: 'tick', 'text-anchor': 'middle' }, text));
    }
    for (const v of yText) {
      root.appendChild(svg('text', { x: box.left - 4, y: ys(v) + 4, class: 'tick', 'text-anchor': 'end' }, short(v)));
    }
  }

  function scatterChart(title, xLabel, yLabel, points, front) {
    const width = 420, height = 300;
    const box = { left: 64, right: width - 16, top: 24, bottom: height - 40 };
    const xr = extent(points.map(function (p) { return p.x; }));
    const yr = extent(points.map(function (p) { return p.y; }));
    const xs = linear(xr[0], xr[1], box.left, box.right), ys = linear(yr[0], yr[1], box.bottom, box.top);
    const root = chartFrame(title, xLabel, yLabel, width, height, box);
    ticks(root, box, xs, ys, [[xr[0], short(xr[0])], [xr[1], short(xr[1])]], [yr[0], yr[1]]);
    if (front.length) {  // a step line: along x at a point's y, then down to the next one's
      let path = 'M' + xs(points[front[0]].x) + ' ' + ys(points[front[0]].y);
      for (let k = 1; k < front.length; k++) {
        const p = points[front[k]];
        path += ' H' + xs(p.x) + ' V' + ys(p.y);
      }
      root.appendChild(svg('path', { d: path, fill: 'none', stroke: groupColour(1),
        'stroke-width': 1.5, class: 'front' }));
    }
    for (const p of points) {
      if (!isFinite(p.x) || !isFinite(p.y)) continue;
      const g = svg('g', { class: p.first ? 'point first-group' : 'point' });
      g.appendChild(svg('title', {}, p.name + ': x ' + fmt(p.x) + ', y ' + fmt(p.y) +
        (p.first ? ' (A* group 1)' : '')));
      if (p.first) {
        g.appendChild(svg('circle', { cx: xs(p.x), cy: ys(p.y), r: 8, fill: 'none',
          stroke: groupColour(1), 'stroke-width': 2 }));
      }
      g.appendChild(svg('circle', { cx: xs(p.x), cy: ys(p.y), r: 3.5, fill: '#333' }));
      g.appendChild(svg('text', { x: xs(p.x) + 8, y: ys(p.y) - 6, class: 'tick' }, p.name));
      root.appendChild(g);
    }
    return el('figure', { className: 'latency-figure' }, [root]);
  }

  function delayChart(name, s, block, methods) {
    const width = 420, height = 300;
    const box = { left: 64, right: width - 100, top: 24, bottom: height - 40 };
    const count = D.seqFrames[s].count;
    const series = methods.map(function (m) { return own(block.delays, D.methods[m]) || []; });
    const all = [];
    for (const rows of series) for (const row of rows) all.push(row[1]);
    const yr = extent(all);
    const xs = linear(1, Math.max(1, count), box.left, box.right), ys = linear(yr[0], yr[1], box.bottom, box.top);
    const root = chartFrame(name + ' · delay per frame', 'frame', D.raw.latency.delay_label,
      width, height, box);
    const labels = [];
    for (let i = 1; i <= count; i++) labels.push(i);
    ticks(root, box, xs, ys, frameTicks(labels).map(function (x) {
      return [labels[x], String(labels[x])];
    }), [yr[0], yr[1]]);
    series.forEach(function (rows, k) {
      const colour = LINE_COLOURS[k % LINE_COLOURS.length];
      if (rows.length) {
        root.appendChild(svg('polyline', { fill: 'none', stroke: colour, 'stroke-width': 1.2,
          class: 'delay-line', points: rows.map(function (row) {
            return xs(row[0] + 1) + ',' + ys(row[1]);
          }).join(' ') }));
      }
      root.appendChild(svg('text', { x: box.right + 8, y: box.top + 12 + 14 * k, class: 'tick',
        style: 'fill:' + colour }, D.methods[methods[k]]));
    });
    return el('figure', { className: 'latency-figure' }, [root]);
  }

  /* Test hook: what the latency view plots (points, front) per sequence. */
  window.dispevalLatency = function () { return D.latencyState; };
