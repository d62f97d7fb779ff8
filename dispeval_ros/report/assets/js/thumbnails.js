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
      el('span', { text: '≥ ' + thumbs.max_error + ' px; ' + (thumbs.note ||
        'black: not evaluated; white lines: criterion borders') }),
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

