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
