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

