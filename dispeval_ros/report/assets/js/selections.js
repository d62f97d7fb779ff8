  // ------------------------------------------------------------------ selections

  function indicesOf(names, map) {
    const wanted = new Set(names || []);
    const out = [];
    for (const [name, i] of map) if (wanted.has(name)) out.push(i);
    return out.sort(function (a, b) { return a - b; });
  }

  /* The chosen frames (global indices) of a sequence: all, or 0-based indices within it. */
  function chosenFrames(s, frames) {
    const span = D.seqFrames[s];
    const name = D.sequences[s].name;
    const out = [];
    if (!frames || !Object.prototype.hasOwnProperty.call(frames, name)) {
      for (let f = 0; f < span.count; f++) out.push(span.offset + f);
      return out;
    }
    const picked = new Set();
    for (const i of frames[name]) if (Number.isInteger(i) && i >= 0 && i < span.count) picked.add(i);
    return Array.from(picked).sort(function (a, b) { return a - b; })
      .map(function (i) { return span.offset + i; });
  }

  /* Frames where every chosen method present in the sequence has a row (data.common_stamps). */
  function commonFrames(s, methods, frames) {
    const needed = methods.filter(function (m) { return D.seqHas[s * D.M + m]; });
    if (!needed.length) return [];
    return chosenFrames(s, frames).filter(function (f) {
      return needed.every(function (m) { return D.framePresent[f * D.M + m]; });
    });
  }

  /* Sums of the rows of (method, criterion) over frames, in frame order; null if none. */
  function totalsOf(frames, c, m) {
    const totals = new Float64Array(D.fields.length);
    let count = 0;
    for (const f of frames) {
      const r = (f * D.C + c) * D.M + m;
      if (!D.present[r]) continue;
      count += 1;
      for (let k = 0; k < totals.length; k++) {
        const column = D.sums[k];
        if (column) totals[k] += column[r];
      }
    }
    return count ? totals : null;
  }

  function objectiveValue(recipe, value) {
    return recipe.higher ? -value : value;
  }

  /* The objective matrix of a selection, as data.selection_objectives builds it in Python. */
  function buildObjectives(selection) {
    const seqs = indicesOf(selection.sequences, D.index.sequence);
    const methods = indicesOf(selection.methods, D.index.method);
    const criteria = indicesOf(selection.criteria, D.index.criterion);
    const measures = indicesOf(selection.measures, D.index.measure);
    const perFrame = selection.granularity === 'frame';
    const points = D.fields.indexOf('n');
    const names = [];
    const columns = [];
    const common = {};
    const totals = {};
    const suffixes = criteria.map(function (c) {
      return measures.map(function (q) {
        return D.criteria[c].name + '/' + D.measures[q].name;
      });
    });
    // a measure gives objectives only on the criteria it is defined on (core.measures.applies):
    // GT measures not on gtfree: criteria, vpe and lrc only there
    const skipped = [];
    criteria.forEach(function (c, ci) {
      measures.forEach(function (q, qi) { if (!applies(c, q)) skipped.push(suffixes[ci][qi]); });
    });
    for (const s of seqs) {
      const frames = commonFrames(s, methods, selection.frames);
      common[s] = frames;
      if (!frames.length || !methods.length) continue;
      const seqName = D.sequences[s].name;
      const seqTotals = {};
      for (const c of criteria) {
        seqTotals[c] = methods.map(function (m) { return totalsOf(frames, c, m); });
      }
      totals[s] = seqTotals;
      if (!perFrame) {
        criteria.forEach(function (c, ci) {
          // a criterion without points there (objectives.has_points) gives no objective
          if (!seqTotals[c].some(function (t) { return t && t[points] > 0; })) return;
          measures.forEach(function (q, qi) {
            if (!applies(c, q)) return;
            const recipe = D.measures[q];
            names.push(suffixes[ci][qi] + ' @' + seqName);
            const column = new Float64Array(methods.length);
            seqTotals[c].forEach(function (t, i) {
              column[i] = t ? objectiveValue(recipe, totalMeasure(recipe, t)) : NaN;
            });
            columns.push(column);
          });
        });
        continue;
      }
      for (const f of frames) {
        const label = ' @' + seqName + ':' + D.sequences[s].stamps[f - D.seqFrames[s].offset];
        criteria.forEach(function (c, ci) {
          const base = (f * D.C + c) * D.M;
          if (!methods.some(function (m) {
            return D.present[base + m] && field(points, base + m) > 0;
          })) return;
          measures.forEach(function (q, qi) {
            if (!applies(c, q)) return;
            const recipe = D.measures[q];
            names.push(suffixes[ci][qi] + label);
            const column = new Float64Array(methods.length);
            for (let i = 0; i < methods.length; i++) {
              const r = base + methods[i];
              column[i] = D.present[r] ? objectiveValue(recipe, rowMeasure(recipe, r)) : NaN;
            }
            columns.push(column);
          });
        });
      }
    }
    const n = methods.length, width = names.length;
    const matrix = new Float64Array(n * width);
    columns.forEach(function (column, k) {
      for (let i = 0; i < n; i++) matrix[i * width + k] = column[i];
    });
    return {
      seqs: seqs, methodIdx: methods, criteria: criteria, measures: measures,
      methods: methods.map(function (m) { return D.methods[m]; }),
      names: names, matrix: matrix, n: n, m: width, common: common, totals: totals,
      skipped: skipped,
    };
  }

  /* Whether measure q is defined on criterion c (reports written before this was recorded:
   * every pair). */
  function applies(c, q) {
    const table = D.criteria[c].applies;
    return !table || table[q] !== false;
  }

  function compute(selection) {
    const t0 = performance.now();
    const built = buildObjectives(selection);
    built.objectivesMs = performance.now() - t0;
    built.models = null;
    if (!built.n) built.problem = 'Select at least one method.';
    else if (!built.m) {
      built.problem = built.skipped.length && built.criteria.length && built.measures.length
        ? 'No objectives: none of the selected measures applies to the selected criteria ' +
          '(ground-truth measures need ground-truth criteria; vpe and lrc need gtfree: criteria).'
        : 'No objectives: select at least one sequence, criterion and measure, and ' +
          'frames that every selected method delivered.';
    } else built.models = evaluateModels(built.methods, built.matrix, built.n, built.m);
    return built;
  }

  /* Test hook: the models of a selection ({sequences, frames, criteria, measures, methods,
   * granularity}), in the JSON form of ModelResult.to_dict plus the objectives. */
  window.dispevalModels = function (selection, withMatrix) {
    if (!D) throw new Error('the report data is not loaded yet');
    const built = compute(selection);
    const out = {
      methods: built.methods, objectives: built.names, skipped: built.skipped, models: null,
    };
    if (withMatrix) {
      out.matrix = [];
      for (let i = 0; i < built.n; i++) {
        out.matrix.push(Array.from(built.matrix.subarray(i * built.m, (i + 1) * built.m)));
      }
    }
    if (built.models) {
      const models = built.models;
      out.models = {
        astar: models.astar, groups: models.groups, reduction: models.reduction,
        reduced: models.reduced, middlebury: models.middlebury,
        interpretation: models.interpretation,
      };
    }
    return out;
  };

  /* The same as a JSON string: keeps a method called "__proto__" as a key; non-finite
   * matrix values become the strings "NaN", "Infinity", "-Infinity". */
  window.dispevalModelsJSON = function (selection, withMatrix) {
    return JSON.stringify(window.dispevalModels(selection, withMatrix), function (key, value) {
      return typeof value === 'number' && !isFinite(value) ? String(value) : value;
    });
  };

