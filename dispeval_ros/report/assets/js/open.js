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
  const TITLE_CHAR_PX = 8;  // a generous width of one character of a chart title (13 px bold)

