  // ---- a parameter sweep (dispeval tune): the best configurations with their values, figures
  // (report/sweep.py builds the data: tune.csv's rows and the sweep's PNG figures)

  /* The section, or nothing for a database dispeval tune did not write. */
  function buildSweepView() {
    const info = D.raw.sweep;
    if (!info || !info.recorded) return null;
    const first = info.headers.length - info.measures.length;  // the measures' columns
    const children = [el('h2', { text: 'Parameter sweep' })];
    children.push(el('p', { className: 'muted small', text: info.configurations +
      ' configurations, best first (A* group, then average rank); ' + info.shown +
      ' shown, every one in tune.csv; the measures over every scene.' }));
    children.push(simpleTable(info.headers, info.rows.map(function (row) {
      return row.map(function (v, i) {
        if (i === 2) return v ? 'yes' : '';
        if (i >= first) return v === null ? '–' : fmt(v);
        return v;
      });
    }), 'sweep-table'));
    const names = Object.keys(info.figures);
    if (!names.length && info.figures_note) {
      children.push(el('p', { className: 'muted small', text: 'Figures: ' + info.figures_note }));
    }
    const plots = el('div', { className: 'bars sweep-figures' });
    for (const name of names) {
      plots.appendChild(el('figure', { className: 'latency-figure' }, [
        el('img', { src: info.figures[name], alt: name, className: 'sweep-figure' }),
        el('figcaption', { className: 'muted small', text: name }),
      ]));
    }
    children.push(plots);
    return el('section', { id: 'sweep-view', className: 'view' }, children);
  }
