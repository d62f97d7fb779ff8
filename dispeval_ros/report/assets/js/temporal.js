  // ---- temporal consistency: pooled TEPE, the ego-motion residual (noise), per pair of frames
  // (report/temporal.py builds the data: summary.json's temporal and egomotion entries)

  /* One table row per method and criterion: method, criterion, its runs (pairs, windows), the
   * count, each column. */
  function methodRows(entries, count, columns, runs) {
    const rows = [];
    for (const method of Object.keys(entries)) {
      const entry = entries[method];
      if (!entry.criteria) continue;  // no pair scored
      for (const criterion of Object.keys(entry.criteria)) {
        const values = entry.criteria[criterion];
        const row = [method, criterion, entry[runs || 'pairs'], values[count]];
        rows.push(row.concat(columns.map((q) => own(values, q))));
      }
    }
    return rows;
  }

  /* The section, or nothing where no pair is recorded (an older database: the page as before). */
  function buildTemporalView() {
    const info = D.raw.temporal;
    D.temporalState = { recorded: !!(info && info.recorded), sequences: {} };
    if (!info || !info.recorded) return null;
    const children = [el('h2', { text: 'Temporal consistency' })];
    for (const name of Object.keys(info.sequences)) {
      const block = info.sequences[name];
      const shown = { tepe: [], residual: [], drift: [], flicker: [] };
      D.temporalState.sequences[name] = shown;
      children.push(el('h3', { text: name }));
      if (block.temporal) {
        shown.tepe = methodRows(block.temporal, 'n_pair', block.tepe_measures);
        children.push(el('p', { className: 'muted small', text: info.tepe_note +
          (info.preset ? ' (preset ' + info.preset + ')' : '') }));
        children.push(simpleTable(['method', 'criterion', 'pairs', 'n_pair', ...block.tepe_headers],
          shown.tepe.map(cells), 'temporal-tepe-' + name));
      }
      if (block.egomotion) {
        const columns = block.residual_columns;
        shown.residual = methodRows(block.egomotion, 'n_residual', columns);
        children.push(el('p', { className: 'muted small noise-note', text: info.noise_note }));
        children.push(simpleTable(['method', 'criterion (noise, not accuracy)', 'pairs',
          'n_residual'].concat(columns.map(residualHeader)), shown.residual.map(cells),
        'temporal-residual-' + name));
      }
      if (block.drift) {
        shown.drift = methodRows(block.drift.methods, 'n', block.drift_columns);
        children.push(el('p', { className: 'muted small noise-note', text: info.drift_note }));
        children.push(simpleTable(['method', 'criterion (noise, not accuracy)', 'pairs', 'n']
          .concat(block.drift_columns.map(function (c) {
            return c + ' [' + (block.drift.units[c] || '') + ']';
          })), shown.drift.map(cells), 'temporal-drift-' + name));
      }
      if (block.flicker) {
        shown.flicker = methodRows(block.flicker.methods, 'n_residual', block.flicker_columns,
          'windows');
        children.push(el('p', { className: 'muted small noise-note', text: info.flicker_note }));
        children.push(simpleTable(['method', 'criterion (noise, not accuracy)', 'windows',
          'n_residual'].concat(block.flicker_columns.map(residualHeader)),
        shown.flicker.map(cells), 'temporal-flicker-' + name));
      }
      const plots = el('div', { className: 'bars temporal-plots' });
      if (Object.keys(block.tepe_series).length) {
        plots.appendChild(pairChart(name + ' · TEPE per pair', info.tepe_label,
          block.tepe_series, block.frames, 'tepe-line'));
      }
      if (Object.keys(block.residual_series).length) {
        plots.appendChild(pairChart(name + ' · ego-motion residual per pair (noise, no GT)',
          info.residual_label, block.residual_series, block.frames, 'residual-line'));
      }
      children.push(plots);
    }
    return el('section', { id: 'temporal-view', className: 'view' }, children);
  }

  function residualHeader(key) {
    return key + (key.indexOf('bad_') === 0 ? ' [%]' : ' [px]');
  }

  /* A table row's cells: counts and names as they are, values as the page writes numbers. */
  function cells(row) {
    return row.map(function (v, i) {
      return i < 2 ? v : (v === null || v === undefined ? '–' : fmt(v));
    });
  }

  /* Each method's value per pair (x: the later frame's number), one line per method. */
  function pairChart(title, yLabel, series, count, cls) {
    const width = 420, height = 300;
    const box = { left: 64, right: width - 100, top: 24, bottom: height - 40 };
    const methods = Object.keys(series);
    const all = [];
    for (const m of methods) for (const row of series[m].values) all.push(row[1]);
    const yr = extent(all);
    const xs = linear(1, Math.max(1, count), box.left, box.right);
    const ys = linear(yr[0], yr[1], box.bottom, box.top);
    const root = chartFrame(title, 'frame (the later of each pair)', yLabel, width, height, box);
    const labels = [];
    for (let i = 1; i <= count; i++) labels.push(i);
    ticks(root, box, xs, ys, frameTicks(labels).map(function (x) {
      return [labels[x], String(labels[x])];
    }), [yr[0], yr[1]]);
    methods.forEach(function (method, k) {
      const colour = LINE_COLOURS[k % LINE_COLOURS.length];
      const rows = series[method].values.filter(function (row) { return row[1] !== null; });
      if (rows.length) {
        root.appendChild(svg('polyline', { fill: 'none', stroke: colour, 'stroke-width': 1.2,
          class: cls, points: rows.map(function (row) {
            return xs(row[0] + 1) + ',' + ys(row[1]);
          }).join(' ') }));
      }
      root.appendChild(svg('text', { x: box.right + 8, y: box.top + 12 + 14 * k, class: 'tick',
        style: 'fill:' + colour }, method));
    });
    return el('figure', { className: 'latency-figure' }, [root]);
  }

  /* Test hook: the rows the temporal tables show (method, criterion, pairs, count, values). */
  window.dispevalTemporal = function () { return D.temporalState; };
