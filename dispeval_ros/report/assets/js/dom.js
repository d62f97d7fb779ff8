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

  /* A canvas of width × height CSS pixels drawn at the screen's pixel density: its 2-D
     context, scaled so that drawing is in CSS pixels. */
  function scaledContext(canvas, width, height) {
    const ratio = window.devicePixelRatio || 1;
    canvas.width = Math.round(width * ratio);
    canvas.height = Math.round(height * ratio);
    canvas.style.width = width + 'px';
    canvas.style.height = height + 'px';
    const ctx = canvas.getContext('2d');
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    return ctx;
  }

  /* The unit of a measure over the chosen methods (SZE without a camera is relative): both
     words come from the recipe (measure_unit in Python), never spelled here. */
  function unitOf(recipe, methodIdx) {
    if (recipe.relative_unit &&
        methodIdx.some(function (m) { return D.raw.relative[m]; })) return recipe.relative_unit;
    return recipe.unit || '';
  }

