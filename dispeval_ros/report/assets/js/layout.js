  // ------------------------------------------------------------------ layout

  function buildLayout() {
    const app = document.getElementById('app');
    clear(app);
    const raw = D.raw;
    const frames = D.F, methods = D.M;
    ui.controls = el('aside', { id: 'controls' });
    const header = el('header', {}, [
      el('h1', { text: raw.title }),
      el('p', { className: 'muted', text: raw.source + ' · ' + D.sequences.length +
        ' sequence(s), ' + frames + ' frames, ' + methods + ' methods, ' + D.C +
        ' criteria · missing estimates: ' + (raw.policy || '?') + ' · made ' + raw.created }),
    ]);
    // what the scores are measured against (a projected LiDAR scan, images without GT, …)
    if (raw.reference) header.appendChild(el('p', { id: 'reference', text: raw.reference }));
    ui.status = el('p', { id: 'status', className: 'status' });
    ui.warnings = el('div', { id: 'warnings' });
    ui.interpretation = el('pre', { id: 'interpretation' });
    ui.middlebury = el('p', { id: 'middlebury-text' });
    ui.table = el('table', { id: 'group-table' });
    ui.objectives = el('p', { id: 'objective-names', className: 'muted small' });
    const models = el('section', { id: 'models-view', className: 'view' }, [
      el('h2', { text: 'Groups, reduced set and interpretation' }), ui.status, ui.warnings,
      ui.interpretation, ui.middlebury, el('div', { className: 'table-wrap' }, [ui.table]),
      ui.objectives,
    ]);

    ui.plotMeasure = el('select', { id: 'plot-measure', 'aria-label': 'plotted measure' });
    D.measures.forEach(function (q, i) {
      ui.plotMeasure.appendChild(el('option', { value: String(i), text: q.name }));
    });
    ui.plotMeasure.value = String(state.plotMeasure);
    ui.plotMeasure.addEventListener('change', function () {
      state.plotMeasure = Number(ui.plotMeasure.value); render();
    });
    ui.plotCriterion = el('select', { id: 'plot-criterion', 'aria-label': 'plotted criterion' });
    D.criteria.forEach(function (c, i) {
      ui.plotCriterion.appendChild(el('option', { value: String(i), text: c.name }));
    });
    ui.plotCriterion.value = String(state.plotCriterion);
    ui.plotCriterion.addEventListener('change', function () {
      state.plotCriterion = Number(ui.plotCriterion.value); render();
    });
    ui.canvas = el('canvas', { id: 'curves' });
    ui.tooltip = el('div', { id: 'tooltip', className: 'tooltip', hidden: '' });
    ui.curvesNote = el('p', { id: 'curves-note', className: 'muted small' });
    const curves = el('section', { id: 'curves-view', className: 'view' }, [
      el('h2', { text: 'Per-frame scores' }),
      el('div', { className: 'plot-controls' }, [
        el('label', {}, [el('span', { text: 'measure ' }), ui.plotMeasure]),
        el('label', {}, [el('span', { text: 'criterion ' }), ui.plotCriterion]),
        el('span', { className: 'legend-fail', text: 'red: frame missing or failed, value ' +
          'undefined, or an outlier of the method (above Q3 + 3·IQR of its frames)' }),
      ]),
      el('div', { className: 'canvas-wrap' }, [ui.canvas, ui.tooltip]), ui.curvesNote,
    ]);
    ui.canvas.addEventListener('mousemove', hoverCurves);
    ui.canvas.addEventListener('mouseleave', function () { ui.tooltip.hidden = true; });

    ui.bars = el('div', { id: 'bars', className: 'bars' });
    ui.barsNote = el('p', { className: 'muted small' });
    const bars = el('section', { id: 'bars-view', className: 'view' }, [
      el('h2', { text: 'Per-criterion totals' }), ui.barsNote, ui.bars,
    ]);

    ui.groupSelect = el('select', { id: 'parallel-group', 'aria-label': 'group' });
    ui.groupSelect.addEventListener('change', function () {
      state.group = Number(ui.groupSelect.value); render();
    });
    ui.parallel = el('div', { id: 'parallel' });
    ui.parallelNote = el('p', { className: 'muted small' });
    const parallel = el('section', { id: 'parallel-view', className: 'view' }, [
      el('h2', { text: 'Front reduction: the u2 terms of a group' }),
      el('div', { className: 'plot-controls' }, [
        el('label', {}, [el('span', { text: 'A* group ' }), ui.groupSelect]),
      ]),
      ui.parallelNote, ui.parallel,
    ]);

    ui.thumbs = el('div', { id: 'thumbnails' });
    const thumbs = el('section', { id: 'thumbs-view', className: 'view' }, [
      el('h2', { text: 'Error maps' }), ui.thumbs,
    ]);

    const run = el('section', { id: 'run-view', className: 'view' }, [
      el('h2', { text: 'Run' }), buildRunInfo(),
    ]);

    const main = el('main', {}, [models, curves, bars, buildLatencyView(), buildTemporalView(),
      buildSweepView(), parallel, thumbs, run]);
    app.appendChild(header);
    app.appendChild(el('div', { className: 'layout' }, [ui.controls, main]));
  }

  function simpleTable(headers, rows, id) {
    const table = el('table', id ? { id: id } : {});
    table.appendChild(el('thead', {}, [el('tr', {}, headers.map(function (h) {
      return el('th', { text: h });
    }))]));
    table.appendChild(el('tbody', {}, rows.map(function (row) {
      return el('tr', {}, row.map(function (cell) {
        return el('td', { text: cell === null || cell === undefined ? '' : String(cell) });
      }));
    })));
    return el('div', { className: 'table-wrap' }, [table]);
  }

  function buildRunInfo() {
    const raw = D.raw;
    const parts = [];
    const counts = [];
    raw.sequences.forEach(function (s) {
      for (const row of s.counts) counts.push([s.name].concat(row));
    });
    parts.push(el('h3', { text: 'Match counts' }));
    parts.push(el('p', { className: 'muted small', text: 'matched: joined and scored; ' +
      'unmatched: no ground-truth frame within the tolerance; dropped: ground-truth frames ' +
      'the method never delivered; failed: joined but not scorable (see problems).' }));
    parts.push(simpleTable(['sequence', 'method', 'matched', 'unmatched', 'dropped', 'failed'],
      counts, 'match-counts'));
    const problems = raw.problems;
    parts.push(el('h3', { text: 'Problems (' + problems.total + ')' }));
    if (problems.total) {
      parts.push(simpleTable(['sequence', 'stamp', 'method', 'message'], problems.shown, 'problems'));
      if (problems.total > problems.shown.length) {
        parts.push(el('p', { className: 'muted', text: 'first ' + problems.shown.length +
          ' of ' + problems.total + ' shown' }));
      }
    } else parts.push(el('p', { className: 'muted', text: 'none recorded' }));
    parts.push(el('details', {}, [
      el('summary', { text: 'Configuration of the run' }),
      el('pre', { text: JSON.stringify(raw.config, null, 2) }),
    ]));
    return el('div', {}, parts);
  }

