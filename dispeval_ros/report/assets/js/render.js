  // ------------------------------------------------------------------ rendering

  let last = null;

  function render() {
    const t0 = performance.now();
    const selection = currentSelection();
    const built = compute(selection);
    const t1 = performance.now();
    last = built;
    renderModels(built, selection);
    const t2 = performance.now();
    renderCurves(built, selection);
    const t3 = performance.now();
    renderBars(built);
    renderLatency(built);
    const t4 = performance.now();
    renderParallel(built);
    const t5 = performance.now();
    renderThumbnails();
    timing.last = performance.now() - t0;
    timing.parts = { objectives: built.objectivesMs, compute: t1 - t0, table: t2 - t1, curves: t3 - t2, bars: t4 - t3, parallel: t5 - t4 };
    timing.renders += 1;
    document.body.dataset.renders = String(timing.renders);
  }

  function renderModels(built, selection) {
    clear(ui.warnings);
    const warn = function (text) { ui.warnings.appendChild(el('p', { className: 'warning', text: text })); };
    const overlapping = built.criteria.filter(function (c) { return D.criteria[c].overlapping; });
    if (overlapping.length) {
      warn('Overlapping legacy criteria selected (' + overlapping.map(function (c) {
        return D.criteria[c].name;
      }).join(', ') + '): their points also belong to other criteria, so errors count more than once.');
    }
    if (selection.granularity === 'sequence' && built.measures.some(function (q) {
      return D.measures[q].kind === 'stored';
    })) warn('Quantile measures are not summable over frames: per sequence they are undefined (worst for every method); choose per-frame objectives.');
    if (built.skipped.length) {
      warn('Skipped ' + built.skipped.length + ' criterion/measure pair' +
        (built.skipped.length === 1 ? '' : 's') + ' that do' + (built.skipped.length === 1 ? 'es' : '') +
        ' not apply (ground-truth measures are undefined on gtfree: criteria, vpe and lrc on ' +
        'ground-truth criteria): ' + built.skipped.slice(0, 8).join(', ') +
        (built.skipped.length > 8 ? ', …' : '') + '.');
    }
    const relative = built.methodIdx.filter(function (m) { return D.raw.relative[m]; });
    if (relative.length && built.measures.some(function (q) { return D.measures[q].name.indexOf('sze') === 0; })) {
      warn('SZE is relative (f·B = 1, no camera) for: ' + relative.map(function (m) { return D.methods[m]; }).join(', '));
    }
    const frameCount = Object.keys(built.common).reduce(function (sum, s) {
      return sum + built.common[s].length;
    }, 0);
    clear(ui.table);
    ui.middlebury.textContent = '';
    if (!built.models) {
      ui.status.textContent = built.problem;
      ui.status.className = 'status problem';
      ui.interpretation.textContent = '';
      ui.objectives.textContent = '';
      return;
    }
    ui.status.className = 'status';
    ui.status.textContent = built.n + ' methods compared on ' + built.m + ' objectives (' +
      (selection.granularity === 'frame' ? 'per criterion and frame' : 'per criterion and sequence') +
      ') over ' + frameCount + ' frames that every selected method delivered; all minimised.';
    const models = built.models;
    ui.interpretation.textContent = models.interpretation;
    const rows = built.methods.map(function (name, i) { return i; });
    if (state.model === 'middlebury') {
      rows.sort(function (a, b) {
        return models.middleburyList[a] - models.middleburyList[b] || a - b;
      });
      ui.middlebury.textContent = 'Middlebury model (for comparison): methods ordered by their ' +
        'average competition rank over the ' + built.m + ' objectives: ' + rows.map(function (i, p) {
          return (p + 1) + '. ' + built.methods[i] + ' (' + models.middleburyList[i].toFixed(2) + ')';
        }).join('; ') + '.';
    } else {
      rows.sort(function (a, b) {
        return models.groupList[a] - models.groupList[b] ||
          models.middleburyList[a] - models.middleburyList[b] || a - b;
      });
    }
    const headers = state.model === 'middlebury'
      ? ['#', 'method', 'avg rank', 'A* group', 'u1', 'u2', 'reduced']
      : ['#', 'method', 'A* group', 'u1', 'u2', 'reduced', 'avg rank'];
    ui.table.appendChild(el('thead', {}, [el('tr', {}, headers.map(function (h) {
      return el('th', { text: h });
    }))]));
    const body = el('tbody');
    rows.forEach(function (i, position) {
      const name = built.methods[i];
      const group = models.groupList[i];
      const pair = models.reduction[name];
      const reduced = models.reduced.indexOf(name) >= 0;
      const cells = {
        '#': el('td', { className: 'c-pos', text: String(position + 1) }),
        method: el('td', { className: 'c-method', text: name }),
        'A* group': el('td', { className: 'c-group', text: String(group) }),
        u1: el('td', { className: 'c-u1', text: pair ? String(pair.u1) : '' }),
        u2: el('td', { className: 'c-u2', text: pair ? pair.u2.toFixed(4) : '' }),
        reduced: el('td', { className: 'c-reduced', text: reduced ? 'yes' : '' }),
        'avg rank': el('td', { className: 'c-rank', text: models.middleburyList[i].toFixed(2) }),
      };
      const tr = el('tr', { className: reduced ? 'reduced' : '' }, headers.map(function (h) {
        return cells[h];
      }));
      tr.dataset.group = String(group);
      tr.dataset.rank = String(models.middleburyList[i]);
      if (pair) { tr.dataset.u1 = String(pair.u1); tr.dataset.u2 = String(pair.u2); }
      cells['A* group'].style.borderLeft = '6px solid ' + groupColour(group);
      body.appendChild(tr);
    });
    ui.table.appendChild(body);
    const shown = built.names.slice(0, 8).join(', ');
    ui.objectives.textContent = 'Objectives: ' + shown +
      (built.names.length > 8 ? ', … (' + built.names.length + ' in all)' : '');
  }

