  // ---- per-criterion bars

  function renderBars(built) {
    clear(ui.bars);
    const recipe = D.measures[state.plotMeasure];
    const seqs = built.seqs.filter(function (s) { return built.totals[s]; });
    if (!built.n || !seqs.length || !built.criteria.length) {
      ui.barsNote.textContent = 'Nothing to show for this selection.';
      return;
    }
    const unit = unitOf(recipe, built.methodIdx);
    const groups = built.models ? built.models.groupList : null;
    // Every method in one group: colour the reduced set instead, so the bars still say something.
    const oneGroup = groups && groups.every(function (g) { return g === groups[0]; });
    const reduced = oneGroup && built.models.reduced ?
      built.methods.map(function (name) { return built.models.reduced.indexOf(name) >= 0; }) : null;
    ui.barsNote.textContent = recipe.name + (unit ? ' (' + unit + ')' : '') +
      ' over the frames every selected method delivered ' +
      '(sums of the per-frame sums' + (seqs.length > 1 ? ', all selected sequences together' : '') +
      '); ' + (reduced ? 'every method is in A* group 1: dark bars = its reduced set.' :
      'bar colour = A* group.') +
      (recipe.kind === 'stored' ? ' Quantiles are not summable: undefined.' : '');
    for (const c of built.criteria) {
      if (!applies(c, state.plotMeasure)) continue;  // e.g. bmp on gtfree: criteria: undefined
      const values = built.methodIdx.map(function (_, i) {
        let totals = null;
        for (const s of seqs) {
          const t = built.totals[s][c][i];
          if (!t) continue;
          if (!totals) totals = new Float64Array(t.length);
          for (let k = 0; k < t.length; k++) totals[k] += t[k];
        }
        return totals ? totalMeasure(recipe, totals) : NaN;
      });
      ui.bars.appendChild(barChart([D.criteria[c].name, recipe.name + (unit ? ' [' + unit + ']' : '')],
        built.methods, values, groups, reduced));
    }
  }

  // Title lines (criterion, then measure [unit]): the chart is made wide enough for them, so a
  // chart of two methods no longer cuts its title ("occluded · sz").
  function barChart(titles, names, values, groups, reduced) {
    const n = names.length;
    const bar = Math.max(4, Math.min(28, Math.floor(560 / Math.max(1, n))));
    const left = 64, bottom = n <= 30 ? 90 : 16, top = 10 + 16 * titles.length;
    const plotHeight = 150;
    const longest = titles.reduce(function (a, t) { return Math.max(a, t.length); }, 0);
    const width = Math.max(left + n * bar + 10, Math.ceil(longest * TITLE_CHAR_PX) + 12);
    const height = top + plotHeight + bottom;
    let ymax = 0;
    for (const v of values) if (isFinite(v) && Math.abs(v) > ymax) ymax = Math.abs(v);
    if (!(ymax > 0)) ymax = 1;
    const root = svg('svg', { width: width, height: height, viewBox: '0 0 ' + width + ' ' + height,
      class: 'bar-chart' });
    titles.forEach(function (t, i) {
      root.appendChild(svg('text', { x: 4, y: 14 + 16 * i, class: i ? 'chart-subtitle' : 'chart-title' }, t));
    });
    root.appendChild(svg('line', { x1: left - 2, y1: top, x2: left - 2, y2: top + plotHeight, class: 'axis' }));
    root.appendChild(svg('line', { x1: left - 2, y1: top + plotHeight, x2: width - 8, y2: top + plotHeight, class: 'axis' }));
    root.appendChild(svg('text', { x: left - 6, y: top + 4, class: 'tick', 'text-anchor': 'end' }, short(ymax)));
    root.appendChild(svg('text', { x: left - 6, y: top + plotHeight, class: 'tick', 'text-anchor': 'end' }, '0'));
    values.forEach(function (v, i) {
      const x = left + i * bar;
      const g = svg('g', {});
      const label = names[i] + ': ' + fmt(v);
      g.appendChild(svg('title', {}, label));
      if (isFinite(v)) {
        const h = (Math.abs(v) / ymax) * plotHeight;
        g.appendChild(svg('rect', { x: x + 1, y: top + plotHeight - h, width: Math.max(1, bar - 2),
          height: Math.max(0.5, h),
          fill: reduced ? (reduced[i] ? '#1f4e8c' : '#a6bddb') : groups ? groupColour(groups[i]) : '#4575b4' }));
      } else {
        g.appendChild(svg('text', { x: x + bar / 2, y: top + plotHeight - 4, class: 'na',
          'text-anchor': 'middle' }, '×'));
      }
      if (n <= 30) {
        const tx = x + bar / 2, ty = top + plotHeight + 8;
        g.appendChild(svg('text', { x: tx, y: ty, class: 'tick', 'text-anchor': 'end',
          transform: 'rotate(-50 ' + tx + ' ' + ty + ')' }, names[i].length > 18 ? names[i].slice(0, 17) + '…' : names[i]));
      }
      root.appendChild(g);
    });
    return el('figure', { className: 'bar-figure' }, [root]);
  }

