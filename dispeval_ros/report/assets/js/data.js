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

