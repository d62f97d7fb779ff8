"""MiddEval3 SDK ``evaldisp``, exactly, and the weighted training-table average.

``err = |d − gt|`` in float32, the error sum ``serr`` accumulated in a float32 in row-major
order, the percentages stored in a float; invalid = ``INF`` (and NaN, which the SDK would score
as a perfect pixel), valid estimates clipped to ``[0, ndisp]``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from dispeval_ros.core.evaluator import as_disparity
from dispeval_ros.core.masks import inside_mask
from dispeval_ros.core.protocols.common import (
    _BAD,
    _BAD_COLUMNS,
    _QUANTILES,
    F32,
    OFFICIAL,
    Arithmetic,
    FrameData,
    FrameResult,
    Protocol,
    ResultLayout,
    _error_columns,
    _same_shape,
    _weighted_mean,
    double_summary,
)
from dispeval_ros.errors import ShapeMismatchError

#: MiddEval3 training scenes and the weights of the weighted average of the training table:
#: PianoL, Playroom, Playtable, Shelves and Vintage count half, the others 1 (15 scenes, total
#: weight 12.5). Scenes not listed (e.g. test scenes) get weight 1.
#: Source: ``MIDDEVAL3_WEIGHTS_SOURCE``.
MIDDEVAL3_WEIGHTS: dict[str, float] = {
    "Adirondack": 1.0,
    "ArtL": 1.0,
    "Jadeplant": 1.0,
    "Motorcycle": 1.0,
    "MotorcycleE": 1.0,
    "Piano": 1.0,
    "PianoL": 0.5,
    "Pipes": 1.0,
    "Playroom": 0.5,
    "Playtable": 0.5,
    "PlaytableP": 1.0,
    "Recycle": 1.0,
    "Shelves": 0.5,
    "Teddy": 1.0,
    "Vintage": 0.5,
}

#: Where ``MIDDEVAL3_WEIGHTS`` come from (the SDK itself has no weights), written into the JSON.
MIDDEVAL3_WEIGHTS_SOURCE = (
    "waychin-weiqin/ITSA @ e345f3927ebec0ac6fe3c2f1c628eeccf879ab53 : eval.py (halves PianoL, "
    "Playroom, Playtable, Shelves, Vintage and divides by 12.5); its author confirms them as the "
    "official MiddEval3 weights in https://github.com/waychin-weiqin/ITSA/issues/2"
)


def middeval3_frame(
    frame: str,
    gt: np.ndarray,
    estimate: np.ndarray,
    nonocc: np.ndarray | None,
    ndisp: float | None,
    arithmetic: Arithmetic = OFFICIAL,
) -> FrameResult:
    """MiddEval3 ``evaldisp`` over ``nonocc`` (mask value 255) and ``all`` (known GT).

    ``estimate`` may be 1/2 or 1/4 of the GT size (upsampled and scaled as the SDK does);
    ``ndisp`` (the GT's calib.txt) bounds valid estimates, ``None`` = the SDK default 99999.
    The SDK takes the bound at the result's resolution: MiddEval3 halves ``ndisp`` per level,
    rounding up (F 290, H 145, Q 73), so a result at 1/s of the GT uses ``ceil(ndisp / s)``.
    """
    gt = as_disparity(gt, "the ground truth")
    estimate = as_disparity(estimate, "the estimate")
    scale = gt.shape[1] // max(estimate.shape[1], 1)
    if (
        scale not in (1, 2, 4)
        or estimate.shape[0] * scale != gt.shape[0]
        or (estimate.shape[1] * scale != gt.shape[1])
    ):
        raise ShapeMismatchError(
            f"the estimate is {estimate.shape[1]}×{estimate.shape[0]} but the ground truth is "
            f"{gt.shape[1]}×{gt.shape[0]}; MiddEval3 needs the GT size exactly 1, 2 or 4 times it"
        )
    d = np.repeat(np.repeat(estimate, scale, axis=0), scale, axis=1) * F32(scale)
    # NaN counts as INF (no estimate / unknown GT): the SDK's ``d == INFINITY`` test lets NaN
    # through, where every comparison is false, so it would score as a perfect pixel.
    known = ~(np.isposinf(gt) | np.isnan(gt))
    valid = ~(np.isposinf(d) | np.isnan(d))
    maxdisp = 99999 if ndisp is None else math.ceil(ndisp / scale)
    maxd = F32(scale * maxdisp)
    with np.errstate(invalid="ignore"):
        d = np.where(valid, np.clip(d, F32(0.0), maxd), d).astype(F32)
        real = arithmetic.real
        error = np.abs(d.astype(real) - gt.astype(real)).astype(real)
    regions: dict[str, np.ndarray] = {}
    if nonocc is not None:
        _same_shape(gt, np.asarray(nonocc), "the nonocc mask (mask0nocc.png)")
        regions["nonocc"] = known & inside_mask("the nonocc mask (mask0nocc.png)", nonocc)
    regions["all"] = known
    result = FrameResult(frame, {})
    if nonocc is None:
        result.notes.append("nonocc: no mask0nocc.png")
    for region, where in regions.items():
        result.values[region] = _middeval3_region(error, valid, where, arithmetic)
    return result


def _middeval3_region(
    error: np.ndarray, valid: np.ndarray, where: np.ndarray, arithmetic: Arithmetic
) -> dict[str, float]:
    n = int(np.count_nonzero(where))
    scored = where & valid
    invalid = n - int(np.count_nonzero(scored))
    errors = error[scored]  # row-major: the SDK's loop order
    values: dict[str, float] = {}
    real = arithmetic.real
    with np.errstate(invalid="ignore", divide="ignore"):
        for threshold in _BAD:
            bad = int(np.count_nonzero(errors > real(threshold)))
            values[f"bad {threshold:.1f}"] = (
                float(real(100.0 * (bad + invalid) / n)) if n else math.nan
            )
        values["invalid"] = float(real(100.0 * invalid / n)) if n else math.nan
        used = n - invalid
        total = arithmetic.accumulate(errors)
        values["avgErr"] = float(total / real(used)) if used else math.nan
        squares = arithmetic.accumulate((errors * errors).astype(real))
        values["rms"] = float(np.sqrt(squares / real(used))) if used else math.nan
    values.update(_quantiles(errors, arithmetic))
    return values


def _quantiles(errors: np.ndarray, arithmetic: Arithmetic = OFFICIAL) -> dict[str, float]:
    """A50…A99: the sorted errors at ``floor(N·q)`` (float32 product), NaN without errors."""
    if errors.size == 0:
        return {f"A{q}": math.nan for q in _QUANTILES}
    positions = {q: min(arithmetic.index(errors.size, q), errors.size - 1) for q in _QUANTILES}
    ordered = np.partition(errors, sorted(set(positions.values())))
    return {f"A{q}": float(ordered[p]) for q, p in positions.items()}


def middeval3_summary(
    frames: Sequence[FrameResult], weights: Mapping[str, float] | None = None
) -> dict[str, dict[str, float]]:
    """Weighted average of every column over the frames (``MIDDEVAL3_WEIGHTS`` by default)."""
    table = MIDDEVAL3_WEIGHTS if weights is None else weights
    return _weighted_mean(frames, [table.get(f.frame, 1.0) for f in frames])


#: The SDK's runalg writes ``disp0NAME.pfm`` into each scene folder; a results folder holds
#: the same per scene, or one PFM per scene.
MIDDEVAL3_RESULTS = ResultLayout(
    folder=("{frame}/disp0{method}.pfm", "{frame}.pfm", "{frame}/disp0.pfm"),
    scene=("disp0{method}.pfm",),
    encoding="pfm",
)


def _frame(data: FrameData, estimate: np.ndarray, arithmetic: Arithmetic) -> FrameResult:
    return middeval3_frame(data.frame, data.gt, estimate, data.nonocc_mask, data.ndisp, arithmetic)


MIDDEVAL3 = Protocol(
    name="middeval3",
    title="Middlebury MiddEval3",
    tool="MiddEval3 SDK evaldisp (runeval)",
    regions=("nonocc", "all"),
    columns=(*_BAD_COLUMNS, "invalid", *_error_columns("avgErr")[len(_BAD) :]),
    percent=(*_BAD_COLUMNS, "invalid"),
    objectives=_error_columns("avgErr"),
    summary="weighted average over scenes (MIDDEVAL3_WEIGHTS)",
    float32="err, the error sums (row-major) and the stored percentages are float32",
    settings={
        "bad_thresholds": list(_BAD),
        "bad_counts_invalid": True,
        "invalid": "+inf or NaN estimate",
        "clip": "valid estimates to [0, ndisp] (scaled with the GT)",
        "avgErr_rms_quantiles_over": "valid estimates",
        "quantile_index": "floor(float32(N) * float32(q))",
        "weights": MIDDEVAL3_WEIGHTS,
        "weights_source": MIDDEVAL3_WEIGHTS_SOURCE,
    },
    frame_function=_frame,
    summary_function=double_summary(middeval3_summary),
    results=MIDDEVAL3_RESULTS,
)
