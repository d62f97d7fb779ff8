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

