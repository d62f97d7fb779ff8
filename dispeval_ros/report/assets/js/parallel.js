  // ---- parallel coordinates of the u2 terms of a group (canvas: thousands of axes are fine)

  function renderParallel(built) {
    clear(ui.parallel);
    clear(ui.groupSelect);
    if (!built.models) {
      ui.parallelNote.textContent = 'Nothing to show for this selection.';
      return;
    }
    const groups = built.models.groupList;
    let count = 1;
    for (const g of groups) if (g > count) count = g;
    for (let g = 1; g <= count; g++) {
      ui.groupSelect.appendChild(el('option', { value: String(g), text: String(g) }));
    }
    if (state.group > count) state.group = 1;
    ui.groupSelect.value = String(state.group);
    const m = built.m;
    let rows, reduction;
    if (state.group === 1) {
      rows = built.models.front.rows;
      reduction = built.models.front.reduction;
    } else {
      rows = [];
      groups.forEach(function (g, i) { if (g === state.group) rows.push(i); });
      const v = asInfMatrix(built.matrix);
      const sub = new Float64Array(rows.length * m);
      rows.forEach(function (row, p) { sub.set(v.subarray(row * m, row * m + m), p * m); });
      reduction = frontReduction(sub, rows.length, m);
    }
    ui.parallelNote.textContent = 'Group ' + state.group + ' (' + rows.length + ' method' +
      (rows.length === 1 ? '' : 's') + '): each line is a method, each axis an objective; the ' +
      'height is (f − min)/(max − min) within the group, and u2 is the sum over the axes. ' +
      'Thick lines: the reduced set of this group (the front of (u1, u2)).';
    const width = Math.max(560, Math.min(1600, ui.parallel.clientWidth || 900));
    const labels = m <= 40;
    const left = labels ? 130 : 40, right = 28, top = 12, plotHeight = 240;
    const bottom = labels ? 150 : 26;
    const height = top + plotHeight + bottom;
    const plotWidth = width - left - right;
    const canvas = el('canvas', { id: 'parallel-canvas' });
    const ctx = scaledContext(canvas, width, height);
    const xOf = function (k) { return left + (m <= 1 ? plotWidth / 2 : (k / (m - 1)) * plotWidth); };
    const yOf = function (t) { return top + (1 - t) * plotHeight; };
    ctx.font = '11px system-ui, sans-serif';
    ctx.strokeStyle = '#c8ced6';
    ctx.lineWidth = 1;
    if (m <= 200) {
      for (let k = 0; k < m; k++) {
        ctx.beginPath(); ctx.moveTo(xOf(k), top); ctx.lineTo(xOf(k), top + plotHeight); ctx.stroke();
      }
    } else {
      ctx.strokeRect(left, top, plotWidth, plotHeight);
    }
    ctx.fillStyle = '#5d6776';
    ctx.textAlign = 'right';
    ctx.textBaseline = 'middle';
    ctx.fillText('1', left - 6, yOf(1));
    ctx.fillText('0', left - 6, yOf(0));
    if (labels) {
      built.names.forEach(function (name, k) {
        ctx.save();
        ctx.translate(xOf(k), top + plotHeight + 8);
        ctx.rotate(-50 * Math.PI / 180);
        ctx.fillText(name.length > 28 ? name.slice(0, 27) + '…' : name, 0, 0);
        ctx.restore();
      });
    } else {
      ctx.textAlign = 'left';
      ctx.fillText(m + ' objectives, in the order of the objective list (labels hidden)', left,
        top + plotHeight + 14);
    }
    const order = rows.map(function (_, p) { return p; }).sort(function (a, b) {
      return reduction.reduced[a] - reduction.reduced[b] || a - b;
    });
    const decimate = m > 2 * plotWidth;
    for (const p of order) {
      const thick = reduction.reduced[p] === 1;
      ctx.strokeStyle = LINE_COLOURS[p % LINE_COLOURS.length];
      ctx.globalAlpha = thick ? 1 : 0.6;
      ctx.lineWidth = thick ? 3 : 1;  // 1 px: Skia's fast hairline path
      ctx.beginPath();
      const terms = reduction.terms;
      ctx.moveTo(xOf(0), yOf(terms[p * m]));
      if (!decimate) {
        for (let k = 1; k < m; k++) ctx.lineTo(xOf(k), yOf(terms[p * m + k]));
      } else {  // per pixel column: the span of the values it holds
        let column = -1, low = 0, high = 0;
        for (let k = 0; k < m; k++) {
          const x = Math.round(xOf(k)), y = yOf(terms[p * m + k]);
          if (x !== column) {
            if (column >= 0) { ctx.lineTo(column, low); ctx.lineTo(column, high); }
            column = x; low = y; high = y;
          } else {
            if (y < low) low = y;
            if (y > high) high = y;
          }
        }
        ctx.lineTo(column, low); ctx.lineTo(column, high);
      }
      ctx.stroke();
    }
    ctx.globalAlpha = 1;
    ui.parallel.appendChild(canvas);
    const legend = el('ul', { className: 'pc-legend' });
    const shown = Math.min(rows.length, 60);
    for (let p = 0; p < shown; p++) {
      const reduced = reduction.reduced[p] === 1;
      const swatch = el('span', { className: 'swatch' });
      swatch.style.background = LINE_COLOURS[p % LINE_COLOURS.length];
      legend.appendChild(el('li', { className: reduced ? 'strong' : '' }, [
        swatch,
        el('span', { text: built.methods[rows[p]] }),
        el('span', { className: 'muted', text: (reduced ? ' ★ reduced' : '') + ' · u1 ' +
          reduction.u1[p] + ' · u2 ' + reduction.u2[p].toFixed(4) }),
      ]));
    }
    if (shown < rows.length) {
      legend.appendChild(el('li', { className: 'muted', text: '… ' + (rows.length - shown) + ' more' }));
    }
    ui.parallel.appendChild(legend);
  }

