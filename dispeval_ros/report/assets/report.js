/* dispeval report: recompute objectives and evaluation models in the browser.
 *
 * Plain JavaScript, no framework, no network. The data element holds the float64 accumulator
 * rows of every (frame, criterion, method) (compressed typed arrays); the models are exact
 * ports of dispeval_ros.core.models (A*, A* Groups, front reduction, Middlebury ranks and the
 * interpretation text), including numpy's pairwise summation for u2, so the results are the
 * Python results bit for bit. Names are data: they are only ever written with textContent.
 */
(function () {
  'use strict';

  const U2_TOLERANCE = 1e-9;
  const PW_BLOCKSIZE = 128;
  const SVG_NS = 'http://www.w3.org/2000/svg';
  const GROUP_COLOURS = ['#1a9850', '#4575b4', '#f46d43', '#984ea3', '#a6761d', '#e7298a',
    '#66a61e', '#1b9e77', '#7570b3', '#d95f02'];
  const LINE_COLOURS = ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd', '#8c564b',
    '#e377c2', '#7f7f7f', '#bcbd22', '#17becf'];
  const FAIL = '#d62728';

  // ------------------------------------------------------------------ numeric helpers

  /* numpy's pairwise summation (add.reduce over a contiguous run), so sums agree bit for bit. */
  function pairwiseSum(a, lo, n) {
    if (n < 8) {
      let res = 0;
      for (let i = 0; i < n; i++) res += a[lo + i];
      return res;
    }
    if (n <= PW_BLOCKSIZE) {
      let r0 = a[lo], r1 = a[lo + 1], r2 = a[lo + 2], r3 = a[lo + 3];
      let r4 = a[lo + 4], r5 = a[lo + 5], r6 = a[lo + 6], r7 = a[lo + 7];
      const end = n - (n % 8);
      let i = 8;
      for (; i < end; i += 8) {
        const p = lo + i;
        r0 += a[p]; r1 += a[p + 1]; r2 += a[p + 2]; r3 += a[p + 3];
        r4 += a[p + 4]; r5 += a[p + 5]; r6 += a[p + 6]; r7 += a[p + 7];
      }
      let res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7));
      for (; i < n; i++) res += a[lo + i];
      return res;
    }
    let n2 = Math.floor(n / 2);
    n2 -= n2 % 8;
    return pairwiseSum(a, lo, n2) + pairwiseSum(a, lo + n2, n - n2);
  }

  function stableOrder(values) {
    const order = new Int32Array(values.length);
    for (let i = 0; i < order.length; i++) order[i] = i;
    order.sort(function (a, b) {
      const x = values[a], y = values[b];
      return x < y ? -1 : x > y ? 1 : a - b;
    });
    return order;
  }

  // ------------------------------------------------------------------ models (core/models.py)

  /* Copy with NaN as +Infinity (a method not scored on an objective is worst there). */
  function asInfMatrix(values) {
    const out = new Float64Array(values.length);
    for (let i = 0; i < values.length; i++) {
      const v = values[i];
      out[i] = v !== v ? Infinity : v;
    }
    return out;
  }

  /* dom[i * n + j] = 1 when row i dominates row j (no worse everywhere, better somewhere). */
  function dominance(v, n, m) {
    const dom = new Uint8Array(n * n);
    for (let i = 0; i < n; i++) {
      const oi = i * m;
      for (let j = i + 1; j < n; j++) {
        const oj = j * m;
        let iLe = true, jLe = true;
        for (let k = 0; k < m; k++) {
          const x = v[oi + k], y = v[oj + k];
          if (x > y) { iLe = false; if (!jLe) break; }
          else if (y > x) { jLe = false; if (!iLe) break; }
        }
        if (iLe && !jLe) dom[i * n + j] = 1;
        else if (jLe && !iLe) dom[j * n + i] = 1;
      }
    }
    return dom;
  }

  function paretoFront(v, n, m) {
    const dom = dominance(v, n, m);
    const front = new Uint8Array(n);
    for (let j = 0; j < n; j++) {
      let dominated = false;
      for (let i = 0; i < n && !dominated; i++) if (dom[i * n + j]) dominated = true;
      front[j] = dominated ? 0 : 1;
    }
    return front;
  }

  function astarGroups(v, n, m) {
    const groups = new Int32Array(n);
    if (n === 0) return groups;
    const dom = dominance(v, n, m);
    const dominators = new Int32Array(n);
    for (let i = 0; i < n; i++) for (let j = 0; j < n; j++) dominators[j] += dom[i * n + j];
    let remaining = n, group = 0;
    while (remaining > 0) {
      group += 1;
      const front = [];
      for (let j = 0; j < n; j++) if (groups[j] === 0 && dominators[j] === 0) front.push(j);
      for (const i of front) { groups[i] = group; remaining -= 1; }
      for (const i of front) for (let j = 0; j < n; j++) dominators[j] -= dom[i * n + j];
    }
    return groups;
  }

  /* Rank each column, 1 = lowest, ties share the lowest rank ("1, 1, 3"): one plus the
   * number of strictly smaller values, found by binary search in the sorted column. */
  function competitionRanks(v, n, m) {
    const ranks = new Int32Array(n * m);
    const column = new Float64Array(n);
    const sorted = new Float64Array(n);
    for (let k = 0; k < m; k++) {
      for (let i = 0; i < n; i++) column[i] = v[i * m + k];
      sorted.set(column);
      sorted.sort();
      for (let i = 0; i < n; i++) {
        const x = column[i];
        let lo = 0, hi = n;
        while (lo < hi) {
          const mid = (lo + hi) >> 1;
          if (sorted[mid] < x) lo = mid + 1; else hi = mid;
        }
        ranks[i * m + k] = lo + 1;
      }
    }
    return ranks;
  }

  /* (f - min) / (max - min) per column; 0 where max = min; an infinite value scores 1. */
  function normalised(v, n, m) {
    const out = new Float64Array(n * m);
    for (let k = 0; k < m; k++) {
      let low = Infinity, high = -Infinity;
      for (let i = 0; i < n; i++) {
        const x = v[i * m + k];
        if (x < low) low = x;
        if (x > high) high = x;
      }
      if (!(high > low)) continue;
      if (isFinite(high)) {
        const span = high - low;
        for (let i = 0; i < n; i++) out[i * m + k] = (v[i * m + k] - low) / span;
      } else {
        for (let i = 0; i < n; i++) out[i * m + k] = v[i * m + k] === Infinity ? 1 : 0;
      }
    }
    return out;
  }

  function snap(values, tolerance) {
    const order = stableOrder(values);
    const snapped = new Float64Array(values.length);
    let first = 0;
    for (let p = 0; p < order.length; p++) {
      if (p > 0 && values[order[p]] - values[order[p - 1]] > tolerance) first = p;
      snapped[order[p]] = values[order[first]];
    }
    return snapped;
  }

  function frontReduction(v, n, m, knownRanks) {
    const ranks = knownRanks || competitionRanks(v, n, m);
    const terms = normalised(v, n, m);
    const u1 = new Float64Array(n), u2 = new Float64Array(n);
    for (let i = 0; i < n; i++) {
      let s = 0;
      for (let k = 0; k < m; k++) s += ranks[i * m + k];
      u1[i] = s;
      u2[i] = pairwiseSum(terms, i * m, m);
    }
    const snapped = snap(u2, U2_TOLERANCE);
    const pairs = new Float64Array(2 * n);
    for (let i = 0; i < n; i++) { pairs[2 * i] = u1[i]; pairs[2 * i + 1] = snapped[i]; }
    return { u1: u1, u2: u2, reduced: paretoFront(pairs, n, 2), terms: terms };
  }

  function middleburyRanks(ranks, n, m) {
    const out = new Float64Array(n);
    for (let i = 0; i < n; i++) {
      let s = 0;
      for (let k = 0; k < m; k++) s += ranks[i * m + k];
      out[i] = m === 0 ? NaN : s / m;
    }
    return out;
  }

  /* The text of dispeval_ros.core.models.interpretation, word for word. */
  function interpretation(methods, groups, reducedNames) {
    if (methods.length === 0) return 'No methods were evaluated.';
    const lines = [];
    const numbers = Array.from(new Set(groups)).sort(function (a, b) { return a - b; });
    for (const group of numbers) {
      const members = methods.filter(function (_, i) { return groups[i] === group; });
      if (group === 1) {
        if (members.length === 1) {
          lines.push('A* = {' + members[0] + '}: a single method of superior performance ' +
            '(it dominates every other method).');
        } else {
          lines.push('A* = {' + members.join(', ') + '}: a set of methods of comparable ' +
            'performance (mutually incomparable; every method outside A* is dominated by at ' +
            'least one of them).');
        }
      } else if (members.length === 1) {
        lines.push('Group ' + group + ': a single method: ' + members[0] + ' (dominated by at ' +
          'least one method of group ' + (group - 1) + ').');
      } else {
        lines.push('Group ' + group + ': ' + members.length + ' methods of comparable ' +
          'performance: ' + members.join(', ') + ' (mutually incomparable; each dominated by ' +
          'at least one method of group ' + (group - 1) + ').');
      }
    }
    if (reducedNames.length) {
      const wanted = new Set(reducedNames);
      const chosen = methods.filter(function (name) { return wanted.has(name); });
      const head = 'Front reduction of A* (chosen without weights, by the (u1, u2) front): ';
      if (chosen.length === 1) lines.push(head + chosen[0] + '.');
      else lines.push(head + chosen.join(', ') + ' (incomparable in (u1, u2)).');
    }
    return lines.join('\n');
  }

  /* evaluate_models: A* Groups, front reduction of group 1, Middlebury ranks, interpretation. */
  function evaluateModels(methods, matrix, n, m) {
    const v = asInfMatrix(matrix);
    const groups = astarGroups(v, n, m);
    const frontRows = [];
    for (let i = 0; i < n; i++) if (groups[i] === 1) frontRows.push(i);
    const sub = new Float64Array(frontRows.length * m);
    frontRows.forEach(function (row, p) { sub.set(v.subarray(row * m, row * m + m), p * m); });
    const ranks = competitionRanks(v, n, m);
    // ranks within the group are the overall ranks when every method is in group 1
    const reduction = frontReduction(sub, frontRows.length, m, frontRows.length === n ? ranks : null);
    const middlebury = middleburyRanks(ranks, n, m);
    // null-prototype maps: a method may be called "__proto__" or "constructor"
    const result = {
      astar: [], groups: Object.create(null), reduction: Object.create(null), reduced: [],
      middlebury: Object.create(null), interpretation: '',
    };
    const groupList = Array.from(groups);
    methods.forEach(function (name, i) {
      result.groups[name] = groups[i];
      result.middlebury[name] = middlebury[i];
    });
    frontRows.forEach(function (row, p) {
      const name = methods[row];
      result.astar.push(name);
      result.reduction[name] = { u1: reduction.u1[p], u2: reduction.u2[p] };
      if (reduction.reduced[p]) result.reduced.push(name);
    });
    result.interpretation = interpretation(methods, groupList, result.reduced);
    result.groupList = groupList;
    result.front = { rows: frontRows, reduction: reduction };
    result.middleburyList = Array.from(middlebury);
    return result;
  }

  // ------------------------------------------------------------------ data

  let D = null;

  function base64Bytes(text) {
    const binary = atob(text);
    const bytes = new Uint8Array(binary.length);
    for (let i = 0; i < binary.length; i++) bytes[i] = binary.charCodeAt(i);
    return bytes;
  }

  async function inflate(bytes) {
    if (typeof DecompressionStream === 'undefined') {
      throw new Error('this browser cannot decompress the report data (DecompressionStream is ' +
        'missing); open the report in a current Chrome, Edge, Firefox or Safari');
    }
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('deflate'));
    return new Uint8Array(await new Response(stream).arrayBuffer());
  }

  const TYPES = {
    u8: [1, Uint8Array], u16: [2, Uint16Array], u32: [4, Uint32Array], f64: [8, Float64Array],
  };

  function decodeColumns(arrays, buffer) {
    const rows = arrays.rows;
    const columns = {};
    let offset = 0;
    for (const column of arrays.columns) {
      if (column.type === 'zero') { columns[column.name] = null; continue; }
      const spec = TYPES[column.type];
      const size = spec[0];
      const bytes = new Uint8Array(rows * size);
      for (let b = 0; b < size; b++) {
        const plane = offset + b * rows;
        for (let i = 0; i < rows; i++) bytes[i * size + b] = buffer[plane + i];
      }
      columns[column.name] = new spec[1](bytes.buffer);
      offset += rows * size;
    }
    if (offset !== buffer.length) throw new Error('the report data is damaged (trailing bytes)');
    return columns;
  }

  async function prepare(raw) {
    const arrays = raw.arrays;
    const buffer = await inflate(base64Bytes(arrays.payload));
    const columns = decodeColumns(arrays, buffer);
    const F = arrays.frames, C = arrays.criteria, M = arrays.methods;
    const data = {
      raw: raw, F: F, C: C, M: M, R: arrays.rows,
      fields: raw.fields, methods: raw.methods, criteria: raw.criteria, measures: raw.measures,
      sequences: raw.sequences, sums: [], stored: {}, present: columns.present,
    };
    data.sums = raw.fields.map(function (name) { return columns['sum:' + name]; });
    for (const name of arrays.stored) data.stored[name] = columns['stored:' + name];
    if (!data.present) data.present = new Uint8Array(data.R);
    let offset = 0;
    data.seqFrames = raw.sequences.map(function (s) {
      const span = { offset: offset, count: s.stamps.length };
      offset += s.stamps.length;
      return span;
    });
    // per (frame, method): any criterion stored; per (sequence, method): any frame stored
    data.framePresent = new Uint8Array(F * M);
    data.seqHas = new Uint8Array(raw.sequences.length * M);
    data.seqOf = new Int32Array(F);
    data.seqFrames.forEach(function (span, s) {
      for (let f = span.offset; f < span.offset + span.count; f++) {
        data.seqOf[f] = s;
        for (let c = 0; c < C; c++) {
          const base = (f * C + c) * M;
          for (let mm = 0; mm < M; mm++) {
            if (data.present[base + mm]) {
              data.framePresent[f * M + mm] = 1;
              data.seqHas[s * M + mm] = 1;
            }
          }
        }
      }
    });
    data.index = {
      sequence: new Map(raw.sequences.map(function (s, i) { return [s.name, i]; })),
      method: new Map(raw.methods.map(function (name, i) { return [name, i]; })),
      criterion: new Map(raw.criteria.map(function (c, i) { return [c.name, i]; })),
      measure: new Map(raw.measures.map(function (m, i) { return [m.name, i]; })),
    };
    return data;
  }

  function field(k, r) {
    const column = D.sums[k];
    return column ? column[r] : 0;
  }

  /* measure_from_sums on a stored row. */
  function rowMeasure(recipe, r) {
    switch (recipe.kind) {
      case 'total': return field(recipe.num, r);
      case 'stored': return D.stored[recipe.name][r];
      default: {
        const den = field(recipe.den, r);
        const value = den > 0 ? recipe.scale * field(recipe.num, r) / den : NaN;
        return recipe.kind === 'sqrt_ratio' ? Math.sqrt(value) : value;
      }
    }
  }

  /* measure_from_sums on summed sums (quantiles are not summable). */
  function totalMeasure(recipe, totals) {
    switch (recipe.kind) {
      case 'total': return totals[recipe.num];
      case 'stored': return NaN;
      default: {
        const den = totals[recipe.den];
        const value = den > 0 ? recipe.scale * totals[recipe.num] / den : NaN;
        return recipe.kind === 'sqrt_ratio' ? Math.sqrt(value) : value;
      }
    }
  }

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
          // a criterion no chosen method has there (no such points) gives no objective
          if (!seqTotals[c].some(function (t) { return t; })) return;
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
          if (!methods.some(function (m) { return D.present[base + m]; })) return;
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

  // ------------------------------------------------------------------ DOM helpers

  function el(tag, options, children) {
    const node = document.createElement(tag);
    if (options) {
      for (const key of Object.keys(options)) {
        const value = options[key];
        if (key === 'text') node.textContent = value;
        else if (key === 'className') node.className = value;
        else if (key === 'dataset') Object.assign(node.dataset, value);
        else node.setAttribute(key, value);
      }
    }
    for (const child of children || []) if (child) node.appendChild(child);
    return node;
  }

  function svg(tag, attrs, text) {
    const node = document.createElementNS(SVG_NS, tag);
    for (const key of Object.keys(attrs || {})) node.setAttribute(key, attrs[key]);
    if (text !== undefined) node.textContent = text;
    return node;
  }

  function clear(node) {
    while (node.firstChild) node.removeChild(node.firstChild);
  }

  function fmt(value) {
    if (value === null || value === undefined || value !== value) return '–';
    if (!isFinite(value)) return value > 0 ? '∞' : '−∞';
    const a = Math.abs(value);
    if (a !== 0 && (a >= 1e6 || a < 1e-3)) return value.toExponential(3);
    if (Number.isInteger(value)) return String(value);
    return String(Number(value.toPrecision(a >= 1000 ? 7 : 5)));
  }

  /* A compact axis label: 3 significant digits, exponent form for large or small values. */
  function short(value) {
    const a = Math.abs(value);
    if (a !== 0 && (a >= 1e4 || a < 1e-2)) return value.toExponential(2).replace('e+', 'e');
    return String(Number(value.toPrecision(3)));
  }

  function groupColour(group) {
    return GROUP_COLOURS[(group - 1) % GROUP_COLOURS.length];
  }

  /* A header stamp (ns, as a decimal string) as seconds since the first frame of its sequence,
     with the stamp itself in seconds: "+1.300 s (1700000001.300 s)". Exact: BigInt. */
  function stampText(stamps, local) {
    const ns = BigInt(stamps[local]), first = BigInt(stamps[0]);
    const seconds = function (v) {
      const sign = v < 0n ? '-' : '', a = v < 0n ? -v : v;
      return sign + (a / 1000000000n) + '.' + String((a % 1000000000n) / 1000000n).padStart(3, '0');
    };
    return '+' + seconds(ns - first) + ' s (' + seconds(ns) + ' s)';
  }

  /* The unit of a measure over the chosen methods (SZE without a camera is relative). */
  function unitOf(recipe, methodIdx) {
    if (recipe.name.indexOf('sze') === 0 &&
        methodIdx.some(function (m) { return D.raw.relative[m]; })) return 'relative, no camera';
    return recipe.unit || '';
  }

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

    const main = el('main', {}, [models, curves, bars, parallel, thumbs, run]);
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
    ui.curvesNote.textContent = recipe.name + ' of criterion ' + D.criteria[c].name + ' on ' +
      frames.length + ' selected frames; common scale 0 – ' + fmt(ymax) +
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
    const ratio = window.devicePixelRatio || 1;
    canvas.width = Math.round(width * ratio);
    canvas.height = Math.round(height * ratio);
    canvas.style.width = width + 'px';
    canvas.style.height = height + 'px';
    const ctx = canvas.getContext('2d');
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
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
    const ticks = Math.min(n, 8);
    for (let t = 0; t < ticks; t++) {
      const x = ticks === 1 ? 0 : Math.round((t / (ticks - 1)) * (n - 1));
      const f = cs.frames[x];
      const s = D.seqOf[f];
      ctx.fillText(String(f - D.seqFrames[s].offset + 1), Math.min(xOf(x), width - 30), height - bottom + 4);
    }
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
      (cs.recipe.unit ? ' ' + cs.recipe.unit : '') + status;
    ui.tooltip.hidden = false;
    ui.tooltip.style.left = Math.min(x + 12, rect.width - 260) + 'px';
    ui.tooltip.style.top = (y + 12) + 'px';
  }

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
      ui.bars.appendChild(barChart(D.criteria[c].name + ' · ' + recipe.name +
        (unit ? ' [' + unit + ']' : ''), built.methods, values, groups, reduced));
    }
  }

  function barChart(title, names, values, groups, reduced) {
    const n = names.length;
    const bar = Math.max(4, Math.min(28, Math.floor(560 / Math.max(1, n))));
    const left = 64, bottom = n <= 30 ? 90 : 16, top = 22;
    const plotHeight = 150;
    const width = left + n * bar + 10, height = top + plotHeight + bottom;
    let ymax = 0;
    for (const v of values) if (isFinite(v) && Math.abs(v) > ymax) ymax = Math.abs(v);
    if (!(ymax > 0)) ymax = 1;
    const root = svg('svg', { width: width, height: height, viewBox: '0 0 ' + width + ' ' + height,
      class: 'bar-chart' });
    root.appendChild(svg('text', { x: left, y: 14, class: 'chart-title' }, title));
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
    const ratio = window.devicePixelRatio || 1;
    canvas.width = Math.round(width * ratio);
    canvas.height = Math.round(height * ratio);
    canvas.style.width = width + 'px';
    canvas.style.height = height + 'px';
    const ctx = canvas.getContext('2d');
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
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

  // ---- error-map thumbnails

  function renderThumbnails() {
    const key = Array.from(state.methods).sort(function (a, b) { return a - b; }).join(',');
    if (ui.thumbsKey === key) return;
    ui.thumbsKey = key;
    clear(ui.thumbs);
    const thumbs = D.raw.thumbnails;
    if (!thumbs || !thumbs.frames || !thumbs.frames.length) {
      ui.thumbs.appendChild(el('p', { className: 'muted', text: 'No error maps: the results ' +
        'database keeps none. Run dispeval report with --bag (the recorded bags) to re-score a ' +
        'few frames and show their error maps here.' }));
      return;
    }
    const legend = el('div', { className: 'thumb-legend' }, [
      el('span', { text: 'error 0 px' }), safeImage(thumbs.legend, 'colour scale'),
      el('span', { text: '≥ ' + thumbs.max_error + ' px; black: not evaluated; white lines: criterion borders' }),
    ]);
    ui.thumbs.appendChild(legend);
    const selected = new Set(Array.from(state.methods).map(function (m) { return D.methods[m]; }));
    for (const frame of thumbs.frames) {
      const images = frame.images.filter(function (pair) { return selected.has(pair[0]); });
      const figure = el('div', { className: 'thumb-frame' }, [
        el('h4', { text: frame.sequence + ' · frame ' + (frame.index + 1) + ' · ' +
          stampText([frame.first_stamp, frame.stamp], 1) }),
      ]);
      const grid = el('div', { className: 'thumb-grid' });
      for (const pair of images) {
        grid.appendChild(el('figure', {}, [safeImage(pair[1], pair[0]), el('figcaption', { text: pair[0] })]));
      }
      if (!images.length) grid.appendChild(el('p', { className: 'muted', text: 'no selected method' }));
      figure.appendChild(grid);
      ui.thumbs.appendChild(figure);
    }
  }

  function safeImage(uri, alt) {
    const img = document.createElement('img');
    if (typeof uri === 'string' && uri.indexOf('data:image/png;base64,') === 0) img.src = uri;
    img.alt = alt;
    return img;
  }

  // ------------------------------------------------------------------ start

  function fatal(error) {
    const app = document.getElementById('app');
    clear(app);
    app.appendChild(el('p', { className: 'problem', text: 'The report cannot be shown: ' +
      (error && error.message ? error.message : String(error)) }));
    document.body.dataset.failed = '1';
  }

  async function main() {
    const node = document.getElementById('dispeval-data');
    const raw = JSON.parse(node.textContent);
    D = await prepare(raw);
    buildLayout();
    buildControls();
    ui.plotMeasure.value = String(state.plotMeasure);
    ui.plotCriterion.value = String(state.plotCriterion);
    render();
    let resizeTimer = null;
    window.addEventListener('resize', function () {
      clearTimeout(resizeTimer);
      resizeTimer = setTimeout(render, 150);
    });
    document.body.dataset.ready = '1';
  }

  main().catch(fatal);
})();
