  // ------------------------------------------------------------------ UI state

  const state = {
    seqs: new Set(), ranges: [], criteria: new Set(), measures: new Set(), methods: new Set(),
    granularity: 'sequence', model: 'astar', plotMeasure: 0, plotCriterion: 0, group: 1,
  };
  const ui = {};
  const timing = { last: 0, renders: 0 };
  window.dispevalTiming = timing;

  function currentSelection() {
    const frames = {};
    let limited = false;
    state.ranges.forEach(function (range, s) {
      const count = D.seqFrames[s].count;
      if (range[0] > 1 || range[1] < count) {
        limited = true;
        const list = [];
        for (let i = range[0] - 1; i < range[1]; i++) list.push(i);
        frames[D.sequences[s].name] = list;
      }
    });
    const names = function (set, list) {
      return list.filter(function (_, i) { return set.has(i); });
    };
    return {
      sequences: names(state.seqs, D.sequences.map(function (s) { return s.name; })),
      frames: limited ? frames : null,
      criteria: names(state.criteria, D.criteria.map(function (c) { return c.name; })),
      measures: names(state.measures, D.measures.map(function (q) { return q.name; })),
      methods: names(state.methods, D.methods),
      granularity: state.granularity,
    };
  }

  window.dispevalSelection = function () {
    const selection = currentSelection();
    selection.model = state.model;
    return selection;
  };

  function checkbox(kind, index, label, checked, set, extra) {
    const input = el('input', { type: 'checkbox', dataset: { kind: kind, index: String(index) } });
    input.checked = checked;
    input.addEventListener('change', function () {
      if (input.checked) set.add(index); else set.delete(index);
      render();
    });
    const row = el('label', { className: 'check' }, [input, el('span', { text: label })]);
    if (extra) row.appendChild(extra);
    return row;
  }

  function radios(name, options, current, onChange) {
    return el('div', { className: 'radios' }, options.map(function (option) {
      const input = el('input', { type: 'radio', name: name, value: option[0] });
      input.checked = option[0] === current;
      input.addEventListener('change', function () { if (input.checked) onChange(option[0]); });
      return el('label', { className: 'check' }, [input, el('span', { text: option[1] })]);
    }));
  }

  function section(title, children, className) {
    return el('section', { className: 'control ' + (className || '') },
      [el('h3', { text: title })].concat(children));
  }

  function buildControls() {
    const raw = D.raw;
    const defaults = raw.defaults;
    D.sequences.forEach(function (s, i) {
      if (defaults.sequences.indexOf(s.name) >= 0) state.seqs.add(i);
      state.ranges.push([1, D.seqFrames[i].count]);
    });
    D.criteria.forEach(function (c, i) { if (defaults.criteria.indexOf(c.name) >= 0) state.criteria.add(i); });
    D.measures.forEach(function (q, i) { if (defaults.measures.indexOf(q.name) >= 0) state.measures.add(i); });
    D.methods.forEach(function (name, i) { if (defaults.methods.indexOf(name) >= 0) state.methods.add(i); });
    state.granularity = defaults.granularity || 'sequence';
    state.model = defaults.model || 'astar';
    const firstMeasure = D.measures.findIndex(function (_, i) { return state.measures.has(i); });
    state.plotMeasure = Math.max(0, firstMeasure);
    const firstCriterion = D.criteria.findIndex(function (_, i) { return state.criteria.has(i); });
    state.plotCriterion = Math.max(0, firstCriterion);

    const aside = ui.controls;
    // sequences and frame ranges
    const seqRows = D.sequences.map(function (s, i) {
      const count = D.seqFrames[i].count;
      const from = el('input', { type: 'number', min: '1', max: String(count), value: '1',
        dataset: { kind: 'frame-from', index: String(i) }, 'aria-label': 'first frame' });
      const to = el('input', { type: 'number', min: '1', max: String(count), value: String(count),
        dataset: { kind: 'frame-to', index: String(i) }, 'aria-label': 'last frame' });
      const update = function () {
        let a = Math.round(Number(from.value)), b = Math.round(Number(to.value));
        if (!isFinite(a)) a = 1;
        if (!isFinite(b)) b = count;
        a = Math.min(Math.max(1, a), count);
        b = Math.min(Math.max(a, b), count);
        from.value = String(a); to.value = String(b);
        state.ranges[i] = [a, b];
        render();
      };
      from.addEventListener('change', update);
      to.addEventListener('change', update);
      const range = el('div', { className: 'range' }, [
        el('span', { text: 'frames' }), from, el('span', { text: '–' }), to,
        el('span', { className: 'muted', text: 'of ' + count }),
      ]);
      return el('div', { className: 'sequence' }, [
        checkbox('sequence', i, s.name, state.seqs.has(i), state.seqs), range,
      ]);
    });
    aside.appendChild(section('Sequences and frames', seqRows));

    aside.appendChild(section('Criteria', D.criteria.map(function (c, i) {
      const tag = c.overlapping ? el('span', { className: 'tag', text: 'overlaps' }) : null;
      return checkbox('criterion', i, c.name, state.criteria.has(i), state.criteria, tag);
    })));

    ui.measureBoxes = [];
    aside.appendChild(section('Objective measures', D.measures.map(function (q, i) {
      let note = null;
      if (q.kind === 'stored') note = el('span', { className: 'tag', text: 'per frame' });
      else if (q.higher) note = el('span', { className: 'tag', text: 'negated' });
      const row = checkbox('measure', i, q.name, state.measures.has(i), state.measures, note);
      ui.measureBoxes.push([q, row]);
      return row;
    }), 'measures'));

    aside.appendChild(section('Objectives', [radios('granularity', [
      ['sequence', 'per (criterion, sequence)'], ['frame', 'per (criterion, frame)'],
    ], state.granularity, function (value) { state.granularity = value; render(); })]));

    aside.appendChild(section('Model', [radios('model', [
      ['astar', 'A* Groups with front reduction'], ['middlebury', 'Middlebury average rank'],
    ], state.model, function (value) { state.model = value; render(); })]));

    const methodBoxes = D.methods.map(function (name, i) {
      return checkbox('method', i, name, state.methods.has(i), state.methods);
    });
    const setAll = function (on) {
      return function () {
        D.methods.forEach(function (_, i) { if (on) state.methods.add(i); else state.methods.delete(i); });
        methodBoxes.forEach(function (row) { row.querySelector('input').checked = on; });
        render();
      };
    };
    const filter = el('input', { type: 'search', placeholder: 'filter methods', 'aria-label': 'filter methods' });
    filter.addEventListener('input', function () {
      const text = filter.value.toLowerCase();
      methodBoxes.forEach(function (row, i) {
        row.hidden = text !== '' && D.methods[i].toLowerCase().indexOf(text) < 0;
      });
    });
    const allButton = el('button', { type: 'button', text: 'all' });
    allButton.addEventListener('click', setAll(true));
    const noneButton = el('button', { type: 'button', text: 'none' });
    noneButton.addEventListener('click', setAll(false));
    aside.appendChild(section('Methods (' + D.methods.length + ')', [
      el('div', { className: 'buttons' }, [allButton, noneButton, filter]),
      el('div', { className: 'method-list' }, methodBoxes),
    ]));
  }

