  // ---- per-frame curves

  function quantileOf(sorted, q) {
    if (!sorted.length) return NaN;
    const pos = (sorted.length - 1) * q;
    const lo = Math.floor(pos), hi = Math.ceil(pos);
    return sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo);
  }

  function renderCurves(built, selection) {
    const recipe = D.measures[state.plotMeasure];
    const c = state.plotCriterion;
    const seqs = built.seqs;
    const frames = [];
    const separators = [];
    for (const s of seqs) {
      if (frames.length) separators.push(frames.length);
      for (const f of chosenFrames(s, selection.frames)) frames.push(f);
    }
    const methods = built.methodIdx;
    const defined = applies(c, state.plotMeasure);  // e.g. vpe on a GT criterion: nothing to plot
    const series = methods.map(function (m) {
      const values = new Float64Array(frames.length);
      const flags = new Uint8Array(frames.length); // 1 missing, 2 undefined, 3 outlier
      const finite = [];
      frames.forEach(function (f, x) {
        if (!defined) {
          values[x] = NaN;
          return;
        }
        const r = (f * D.C + c) * D.M + m;
        if (!D.present[r]) {
          values[x] = NaN;
          flags[x] = D.framePresent[f * D.M + m] ? 2 : 1;
          return;
        }
        const value = rowMeasure(recipe, r);
        values[x] = value;
        if (value !== value) flags[x] = 2;
        else finite.push(value);
      });
      finite.sort(function (a, b) { return a - b; });
      const q1 = quantileOf(finite, 0.25), q3 = quantileOf(finite, 0.75);
      const spread = 3 * (q3 - q1);
      let top = -Infinity;
      for (let x = 0; x < values.length; x++) {
        const v = values[x];
        if (v !== v) continue;
        const outlier = spread > 0 && (recipe.higher ? v < q1 - spread : v > q3 + spread);
        if (outlier) flags[x] = 3;
        else if (v > top) top = v;
      }
      return { values: values, flags: flags, top: top };
    });
    let ymax = 0;
    for (const s of series) if (isFinite(s.top) && s.top > ymax) ymax = s.top;
    if (!(ymax > 0)) ymax = 1;
    D.curveState = {
      frames: frames, series: series, methods: methods, ymax: ymax, recipe: recipe, defined: defined,
    };
    drawCurves(separators);
    const failures = series.reduce(function (sum, s) {
      let count = 0;
      for (const flag of s.flags) if (flag) count += 1;
      return sum + count;
    }, 0);
    if (!defined) {
      ui.curvesNote.textContent = recipe.name + ' is not defined on criterion ' +
        D.criteria[c].name + ' (ground-truth measures need a GT criterion, vpe and lrc a ' +
        'gtfree: one): nothing to plot; choose another measure or criterion.';
      return;
    }
    const unit = unitOf(recipe, methods);
    ui.curvesNote.textContent = recipe.name + (unit ? ' [' + unit + ']' : '') + ' of criterion ' +
      D.criteria[c].name + ' on ' + frames.length + ' selected frames (x: frame number); ' +
      'common scale 0 – ' + fmt(ymax) + (unit ? ' ' + unit : '') +
      ' (outliers drawn at the top); ' + failures + ' red marks.' +
      (recipe.kind === 'stored' ? '' : ' Values from the stored sums.');
  }

  function drawCurves(separators) {
    const cs = D.curveState;
    const canvas = ui.canvas;
    const labelWidth = 170, right = 12, top = 8, bottom = 22;
    const rowHeight = cs.methods.length > 40 ? 16 : 26;
    const width = Math.max(480, (canvas.parentNode && canvas.parentNode.clientWidth) || 900);
    const height = top + bottom + Math.max(1, cs.methods.length) * rowHeight;
    const ctx = scaledContext(canvas, width, height);
    ctx.clearRect(0, 0, width, height);
    const plotWidth = width - labelWidth - right;
    const n = cs.frames.length;
    const xOf = function (x) { return labelWidth + (n <= 1 ? plotWidth / 2 : (x / (n - 1)) * plotWidth); };
    const step = n > 1 ? plotWidth / (n - 1) : plotWidth;
    cs.geometry = { labelWidth: labelWidth, top: top, rowHeight: rowHeight, plotWidth: plotWidth, n: n };
    ctx.font = '12px system-ui, sans-serif';
    ctx.textBaseline = 'middle';
    cs.methods.forEach(function (m, row) {
      const y0 = top + row * rowHeight;
      ctx.fillStyle = row % 2 ? '#f6f7f9' : '#ffffff';
      ctx.fillRect(labelWidth, y0, plotWidth, rowHeight);
      const s = cs.series[row];
      // failures first, as red bands and ticks
      for (let x = 0; x < n; x++) {
        const flag = s.flags[x];
        if (flag === 1 || flag === 2) {
          ctx.fillStyle = flag === 1 ? 'rgba(214,39,40,0.55)' : 'rgba(214,39,40,0.8)';
          const w = Math.max(3, step);
          ctx.fillRect(xOf(x) - w / 2, y0 + 1, w, rowHeight - 2);
        }
      }
      const yOf = function (v) {
        const clipped = Math.min(Math.max(v, 0), cs.ymax);
        return y0 + rowHeight - 3 - (clipped / cs.ymax) * (rowHeight - 6);
      };
      ctx.strokeStyle = LINE_COLOURS[row % LINE_COLOURS.length];
      ctx.lineWidth = 1;
      ctx.beginPath();
      let open = false;
      for (let x = 0; x < n; x++) {
        const v = s.values[x];
        if (v !== v) { open = false; continue; }
        const px = xOf(x), py = yOf(v);
        if (open) ctx.lineTo(px, py); else { ctx.moveTo(px, py); open = true; }
      }
      ctx.stroke();
      ctx.fillStyle = FAIL;
      for (let x = 0; x < n; x++) {
        if (s.flags[x] !== 3) continue;
        ctx.beginPath();
        ctx.arc(xOf(x), yOf(s.values[x]), 3, 0, 2 * Math.PI);
        ctx.fill();
      }
      ctx.fillStyle = '#222';
      ctx.save();
      ctx.beginPath();
      ctx.rect(0, y0, labelWidth - 6, rowHeight);
      ctx.clip();
      ctx.fillText(D.methods[m], 4, y0 + rowHeight / 2);
      ctx.restore();
    });
    ctx.strokeStyle = '#555';
    ctx.lineWidth = 1;
    for (const x of separators) {
      const px = xOf(x) - step / 2;
      ctx.beginPath(); ctx.moveTo(px, top); ctx.lineTo(px, height - bottom); ctx.stroke();
    }
    ctx.fillStyle = '#555';
    ctx.textBaseline = 'top';
    const labels = cs.frames.map(function (f) { return f - D.seqFrames[D.seqOf[f]].offset + 1; });
    for (const x of frameTicks(labels)) {
      ctx.fillText(String(labels[x]), Math.min(xOf(x), width - 30), height - bottom + 4);
    }
  }

  // Frame-number ticks: whole frame numbers at a round step (1, 2, 5, 10, 20, …; about 8 at
  // most), and the first frame; never a fraction of a frame.
  function frameTicks(labels) {
    const n = labels.length;
    let step = 1;
    for (let k = 0; n / step > 8; k++) step = [2, 5, 10][k % 3] * Math.pow(10, Math.floor(k / 3));
    const ticks = n ? [0] : [];
    for (let x = 1; x < n; x++) {
      if (labels[x] % step === 0 && x - ticks[ticks.length - 1] >= step / 2) ticks.push(x);
    }
    return ticks;
  }

  function hoverCurves(event) {
    const cs = D.curveState;
    if (!cs || !cs.geometry) return;
    const g = cs.geometry;
    const rect = ui.canvas.getBoundingClientRect();
    const x = event.clientX - rect.left, y = event.clientY - rect.top;
    const row = Math.floor((y - g.top) / g.rowHeight);
    if (x < g.labelWidth || row < 0 || row >= cs.methods.length || !g.n) {
      ui.tooltip.hidden = true;
      return;
    }
    const index = g.n <= 1 ? 0 : Math.round(((x - g.labelWidth) / g.plotWidth) * (g.n - 1));
    const f = cs.frames[Math.min(Math.max(index, 0), g.n - 1)];
    const s = D.seqOf[f];
    const local = f - D.seqFrames[s].offset;
    const series = cs.series[row];
    const at = Math.min(Math.max(index, 0), g.n - 1);
    const flag = series.flags[at];
    if (!cs.defined) {
      ui.tooltip.hidden = true;
      return;
    }
    const status = ['', ' (missing: no scores for this frame)', ' (undefined)', ' (outlier)'][flag];
    ui.tooltip.textContent = D.methods[cs.methods[row]] + ' · ' + D.sequences[s].name +
      ' frame ' + (local + 1) + ' (' + stampText(D.sequences[s].stamps, local) + ') · ' +
      cs.recipe.name + ' = ' + fmt(series.values[at]) +
      (unitOf(cs.recipe, cs.methods) ? ' ' + unitOf(cs.recipe, cs.methods) : '') + status;
    ui.tooltip.hidden = false;
    ui.tooltip.style.left = Math.min(x + 12, rect.width - 260) + 'px';
    ui.tooltip.style.top = (y + 12) + 'px';
  }

