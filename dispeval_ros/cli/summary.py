"""Human-readable scores and model results (shared by eval, demo and later commands)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from dispeval_ros.cli.output import plural, table, text_width, wrapped
from dispeval_ros.core import ModelResult
from dispeval_ros.core.egomotion import STATUS_NAMES
from dispeval_ros.core.lidar_drift import LABEL as DRIFT_LABEL
from dispeval_ros.core.lidar_drift import PREFIX as DRIFT_PREFIX
from dispeval_ros.core.lidar_drift import STATUS_NAMES as DRIFT_STATUS
from dispeval_ros.core.lidar_drift import DriftOptions, DriftSums
from dispeval_ros.core.measures import DEPTH_MEASURES, GT_FREE_PREFIX, applies, measure_unit
from dispeval_ros.core.objectives import has_points
from dispeval_ros.core.timing import TIMING_MEASURES, WINDOW_NS
from dispeval_ros.summary import FLICKER_LABEL

ScoreTable = Mapping[str, Mapping[str, float]]
GT_FREE_LABEL = "  (ground-truth-free: from the left and right images, no GT)"


def measure_header(name: str, relative: bool = False) -> str:
    """A measure's column header with its unit: ``sze [m]``, ``bmp [%]``."""
    unit = measure_unit(name, relative)
    return f"{name} [{unit}]" if unit else name


def fitted_tables(
    header: Sequence[str],
    rows: Sequence[Sequence[object]],
    keep: int,
    width: int | None = None,
    render: Callable[[list[Any], list[list[Any]]], str] = table,
) -> str:
    """``render`` (``table``), split by columns into tables no wider than :func:`text_width`.

    The first ``keep`` columns (method, n) are repeated in every part.
    """
    limit = width or text_width()
    parts: list[str] = []
    start = keep
    while start < len(header) or not parts:
        end = start + 1
        while end < len(header):
            columns = [*range(keep), *range(start, end + 1)]
            text = render([header[i] for i in columns], [[r[i] for i in columns] for r in rows])
            if max(len(line) for line in text.splitlines()) > limit:
                break
            end += 1
        columns = [*range(keep), *range(start, min(end, len(header)))]
        parts.append(render([header[i] for i in columns], [[r[i] for i in columns] for r in rows]))
        start = end
    return "\n\n".join(parts)


def empty_note(scores: Mapping[str, ScoreTable], criterion: str) -> str:
    """Below the table of a criterion without points: why, and that it is no objective."""
    if not scores or has_points(scores, criterion):
        return ""
    from dispeval_ros.core.criteria.empty import empty_reason  # loads the kernels: only here

    name = criterion.removeprefix(GT_FREE_PREFIX)
    return "\n" + wrapped(f"{name}: no point — {empty_reason(criterion)}; not an objective")


def _criterion_block(
    title: str, scores: Mapping[str, ScoreTable], criterion: str, shown: Sequence[str], rel: bool
) -> str:
    header = ["method", "n", *(measure_header(m, rel) for m in shown)]
    rows = [
        [method, int(values[criterion]["n"]), *(values[criterion][m] for m in shown)]
        for method, values in scores.items()
    ]
    return (
        wrapped(title) + "\n" + fitted_tables(header, rows, keep=2) + empty_note(scores, criterion)
    )


def scores_text(
    scores: Mapping[str, ScoreTable],
    measures: Sequence[str],
    overlapping: Sequence[str] = (),
    relative: bool = False,
) -> str:
    """One table per criterion (split to the terminal's width): a row per method.

    A criterion shows the measures defined on it: ground-truth-free criteria (``gtfree:``)
    the GT-free measures and density, the others the GT measures. A criterion without points
    says why (:func:`empty_note`).
    """
    blocks = []
    methods = list(scores)
    criteria = list(scores[methods[0]]) if methods else []
    for criterion in criteria:
        shown = [m for m in measures if applies(m, criterion)]
        title = f"criterion: {criterion}"
        if criterion in overlapping:
            title += "  (legacy Middlebury criterion: overlaps the others)"
        if criterion.startswith(GT_FREE_PREFIX):
            title += GT_FREE_LABEL
        blocks.append(_criterion_block(title, scores, criterion, shown, relative))
    return "\n\n".join(blocks)


def _frame_names(objectives: Sequence[str]) -> tuple[list[str], int]:
    """Objective names with frames as ``fNN`` instead of stamps, and how many were renamed.

    A per-frame objective is ``criterion/measure @sequence:stamp`` (the stamp in ns, as the
    exports keep it); ``fNN`` counts the frames of its sequence from ``f00``, in stamp order.
    """
    stamps: dict[str, set[int]] = {}
    parsed = []
    for name in objectives:
        head, at, where = name.rpartition(" @")
        sequence, colon, stamp = where.rpartition(":")
        if at and colon and stamp.isdigit():
            stamps.setdefault(sequence, set()).add(int(stamp))
            parsed.append((head, sequence, stamp))
        else:
            parsed.append((name, "", ""))
    frames = {
        sequence: {str(s): i for i, s in enumerate(sorted(seen))}
        for sequence, seen in stamps.items()
    }
    short = []
    for (head, sequence, stamp), name in zip(parsed, objectives, strict=True):
        if not stamp:
            short.append(name)
            continue
        digits = max(2, len(str(len(frames[sequence]) - 1)))
        short.append(f"{head} @{sequence}:f{frames[sequence][stamp]:0{digits}d}")
    return short, sum(1 for p in parsed if p[2])


_KEEP = "\u00a0"
"""Stands for a space textwrap must not break at (it breaks at ASCII whitespace only)."""


def models_text(result: ModelResult, objectives: Sequence[str]) -> str:
    """Groups, front reduction and Middlebury ranks as a table, then the interpretation."""
    rows = []
    for method in sorted(result.methods, key=lambda m: (result.groups[m], result.middlebury[m])):
        reduction = result.reduction.get(method)
        rows.append(
            [
                method,
                result.groups[method],
                reduction["u1"] if reduction else "",
                reduction["u2"] if reduction else "",
                "yes" if method in result.reduced else "",
                result.middlebury[method],
            ]
        )
    header = ["method", "A* group", "u1", "u2", "reduced", "avg rank"]
    names, framed = _frame_names(objectives)
    shown = ", ".join(n.replace(" ", _KEEP) for n in names[:6])  # a name stays on one line
    shown += f", … ({len(names)} in all)" if len(names) > 6 else ""
    legend = (
        "\nfNN: the frames every method delivered, from f00 in stamp order (the JSON and the "
        "--export CSV name them by stamp)"
        if framed
        else ""
    )
    return (
        wrapped(
            f"A* Groups over {plural(len(names), 'objective')} ({shown}), all minimised"
        ).replace(_KEEP, " ")
        + wrapped(legend)
        + "\n"
        + table(header, rows)
        + "\n\n"
        + wrapped(result.interpretation)
    )


SEQUENCE_MEASURES = (
    "density", "bmp", "mae", "d1", "sze", "sze_mean", "bmpre", "vpe", "lrc", *DEPTH_MEASURES
)  # fmt: skip
"""Shown per sequence: SZE is a sum (its size grows with the points); sze_mean is per point.
The depth-domain measures (LiDAR runs) where they were computed."""


TIMING_SHOWN = (
    "latency_median", "latency_p95", "latency_max", "fps", "fps_min", "jitter_mean", "jitter_max"
)  # fmt: skip
"""The timing measures of the latency table (``missed`` has its own column after frames)."""
NO_LATENCY = (
    "latency: not recorded (results written before dispeval recorded arrival times; "
    "a run resumed onto them records none either)"
)


def latency_text(timing: Mapping[str, Any] | None) -> str:
    """A sequence's latency table (one row per method), or why there is none; '' if none.

    ``timing``: method → :class:`~dispeval_ros.core.timing.Timing`; None: not recorded;
    empty: nothing arrived with a time (scored from files).
    """
    if timing is None:
        return wrapped(NO_LATENCY)
    if not timing:
        return ""
    header = [
        "method",
        "frames",
        "missed",
        *(f"{n} [{TIMING_MEASURES[n].unit}]" for n in TIMING_SHOWN),
    ]
    rows = [
        [method, t.frames, t.missed, *(t.value(n) for n in TIMING_SHOWN)]
        for method, t in timing.items()
    ]
    title = (
        "\nlatency: arrival − header stamp (log time in a bag, receipt time live) over every "
        f"frame each method delivered; fps_min: the slowest complete {WINDOW_NS / 1e9:g} s window"
    )
    return wrapped(title) + "\n" + fitted_tables(header, rows, keep=1)


def pair_table(
    values: Mapping[str, Mapping[str, Mapping[str, float]]], measures: Sequence[str]
) -> str:
    """Pair measures by criterion and method (``values``: method → criterion → measure)."""
    from dispeval_ros.core.temporal import pair_unit

    header = ["criterion", "method", "n_pair", *(f"{m} [{pair_unit(m)}]" for m in measures)]
    rows: list[list[object]] = []
    for criterion in next(iter(values.values())):
        for method, by_criterion in values.items():
            one = by_criterion[criterion]
            rows.append([criterion, method, int(one["n_pair"]), *(one[m] for m in measures)])
    return fitted_tables(header, rows, keep=2)


NO_PAIRS = (
    "temporal: not recorded (results written before dispeval stored pairs of consecutive frames)"
)


def temporal_text(pairs: Mapping[str, Any] | None, preset: str) -> str:
    """A sequence's pair measures (``--temporal``), or why there are none.

    ``pairs``: method → its pooled :class:`~dispeval_ros.core.temporal.PairScores`; None: not
    recorded; empty: no method has two consecutive frames.
    """
    if pairs is None:
        return wrapped(NO_PAIRS)
    if not pairs:
        return wrapped("\ntemporal: no pair (no method has an estimate of two consecutive frames)")
    first = next(iter(pairs.values()))
    title = (
        f"\ntemporal consistency (--temporal {preset}: {first.preset.description}; each "
        "method's pairs of consecutive frames pooled by their sums): "
        + ", ".join(f"{method} {plural(p.pairs, 'pair')}" for method, p in pairs.items())
    )
    table_text = pair_table({m: p.to_dict() for m, p in pairs.items()}, first.measures)
    return wrapped(title) + "\n" + table_text


EGOMOTION_LABEL = (
    "ground-truth-free: temporal noise of the estimate moved by the camera's motion, no GT; "
    "not bias (a constant offset is fitted and removed per pair)"
)
"""What every ego-motion residual output says it is (``eval --egomotion``'s text title and
JSON ``label``, the bag tables' title)."""
EGOMOTION_MASKED = tuple(f"n_{name}" for name in STATUS_NAMES[1:])
"""The mask counts of the residual's tables, in the order the masks apply."""


DRIFT_DROPPED = tuple(f"n_{name}" for name in DRIFT_STATUS[1:])
"""The drop counts of the drift tables, in the order the tests apply."""


def drift_text(
    options: DriftOptions,
    drift: Mapping[str, DriftSums | None],
    pairs: Mapping[str, int] | None = None,
) -> str:
    """The LiDAR drift table: criterion, method, (pairs,) points, counted, values, drop counts.

    ``drift``: each method's pooled sums (None: no pair scored); ``pairs``: how many pairs
    each pooled (a column when given). ``eval --egomotion`` and the bag tables both print it.
    """
    bad = [f"bad_{t:g}" for t in options.thresholds]
    header = [
        "criterion", "method", *(["pairs"] if pairs is not None else []), "points",
        "counted [%]", "mean [px]", "rms [px]", *(f"{b} [%]" for b in bad), "bias_drift [px]",
        *DRIFT_DROPPED,
    ]  # fmt: skip
    rows: list[list[object]] = []
    scored = {m: pooled for m, pooled in drift.items() if pooled is not None}
    for criterion in next(iter(scored.values())).criteria if scored else ():
        for method, pooled in scored.items():
            one = pooled.summary(criterion)
            rows.append([
                DRIFT_PREFIX + criterion, method,
                *([pairs.get(method, 0)] if pairs is not None else []), int(one["n"]),
                one["counted"], one["mean"], one["rms"], *(one[b] for b in bad),
                one["bias_drift"], *(int(one[d]) for d in DRIFT_DROPPED),
            ])  # fmt: skip
    visibility = options.visibility
    title = wrapped(
        f"LiDAR drift between scans ({DRIFT_LABEL}; missing estimates: "
        f"{options.missing}; hidden: a point of scan t + k nearer by more than "
        f"{100 * visibility.gap:g} % within {visibility.window}×{visibility.window} px)"
    )
    return title + "\n" + (fitted_tables(header, rows, keep=2) if rows else "no pair was scored")


def egomotion_text(motion: Mapping[str, Any] | None) -> str:
    """A sequence's ego-motion residuals (``egomotion``), or why there are none.

    ``motion``: method → (pairs, pooled :class:`~dispeval_ros.core.egomotion.TemporalSums`);
    None: not recorded; empty: no pair.
    """
    if motion is None:
        return wrapped("\nego-motion residual: not recorded (results older than it)")
    if not motion:
        return wrapped("\nego-motion residual: no pair (no method has two consecutive frames)")
    first = next(iter(motion.values()))[1]
    bad = [f"bad_{t:g}" for t in first.thresholds]
    header = [
        "criterion", "method", "pairs", "n_residual", "mean_abs [px]", "rms [px]",
        *(f"{b} [%]" for b in bad), "mean_abs_z [m]", "rms_z [m]", *EGOMOTION_MASKED,
    ]  # fmt: skip
    rows: list[list[object]] = []
    for criterion in first.criteria:
        for method, (pairs, sums) in motion.items():
            one = sums.summary(criterion)
            rows.append([
                GT_FREE_PREFIX + criterion, method, pairs, int(one["n_residual"]),
                one["mean_abs"], one["rms"], *(one[b] for b in bad), one["mean_abs_z"],
                one["rms_z"], *(int(one[m]) for m in EGOMOTION_MASKED),
            ])  # fmt: skip
    title = (
        f"\nego-motion residual of each method's pairs of consecutive frames ({EGOMOTION_LABEL})"
    )
    return wrapped(title) + "\n" + fitted_tables(header, rows, keep=2)


FLICKER_MASKED = ("n_missing", "n_edge", "n_moving")
"""The masks flicker applies (an estimate missing in a frame, a depth edge, a changing image)."""


def confidence_text(confidence: Mapping[str, Any] | None) -> str:
    """A sequence's confidence curves: method → (frames, preset, pooled sums), or why none."""
    from dispeval_ros.cli import confidence_eval

    if confidence is None:
        return wrapped("\nconfidence: not recorded (results older than it)")
    if not confidence:
        return wrapped("\nconfidence: no frame with both an estimate and its confidence map")
    heading = "; ".join(
        f"{method}: {frames} frames, preset {preset}"
        for method, (frames, preset, _) in confidence.items()
    )
    summaries = {method: sums.summary() for method, (_, _, sums) in confidence.items()}
    return wrapped(f"\nconfidence ({heading})") + "\n" + confidence_eval.text(summaries)


def flicker_text(flicker: Mapping[str, Any] | None) -> str:
    """A sequence's flicker (``flicker``): method → (windows, frames, pooled sums), or why none."""
    if flicker is None:
        return wrapped("\nflicker: not recorded (results older than it)")
    if not flicker:
        return wrapped("\nflicker: no window (no method has two consecutive frames)")
    first = next(iter(flicker.values()))[2]
    bad = [f"bad_{t:g}" for t in first.thresholds]
    header = [
        "criterion", "method", "windows", "frames", "n_residual", "mean [px]", "rms [px]",
        *(f"{b} [%]" for b in bad), "mean_z [m]", *FLICKER_MASKED,
    ]  # fmt: skip
    rows: list[list[object]] = []
    for criterion in first.criteria:
        for method, (windows, frames, sums) in flicker.items():
            one = sums.summary(criterion)
            rows.append([
                GT_FREE_PREFIX + criterion, method, windows, frames, int(one["n_residual"]),
                one["mean"], one["rms"], *(one[b] for b in bad), one["mean_abs_z"],
                *(int(one[m]) for m in FLICKER_MASKED),
            ])  # fmt: skip
    title = (
        "\nflicker: each method's per-pixel spread (std, ddof 1) over its windows of "
        f"consecutive frames ({FLICKER_LABEL})"
    )
    return wrapped(title) + "\n" + fitted_tables(header, rows, keep=2)


def run_summary_text(summary: Any, problems: Sequence[Any] = ()) -> str:
    """Per-sequence counts, scores over the common frames and models; then all sequences."""
    parts = []
    for sequence in summary.sequences:
        parts.append(
            f"\n=== sequence {sequence.sequence}: {plural(sequence.common_frames, 'frame')} with "
            "every method"
        )
        parts.append(
            table(
                ["method", "matched", "unmatched", "dropped", "failed"],
                [
                    [m, c.matched, c.unmatched, c.dropped, c.failed]
                    for m, c in sequence.counts.items()
                ],
            )
        )
        latency = latency_text(sequence.timing)
        if latency:
            parts.append(latency)
        if summary.temporal:
            parts.append(temporal_text(sequence.pairs, summary.temporal))
        if getattr(summary, "egomotion", False):
            parts.append(egomotion_text(sequence.motion))
            if getattr(sequence, "drift", None):  # only with LiDAR ground truth
                drift = sequence.drift
                options = next(iter(drift.values()))[1].options or DriftOptions()
                pooled = {m: sums for m, (_, sums) in drift.items()}
                pairs = {m: n for m, (n, _) in drift.items()}
                parts.append("\n" + drift_text(options, pooled, pairs))
        if getattr(summary, "flicker", False):
            parts.append(flicker_text(sequence.flicker))
        if getattr(summary, "confidence", False):
            parts.append(confidence_text(sequence.confidence))
        if sequence.scores:
            first = next(iter(sequence.scores.values()))
            measures = [m for m in SEQUENCE_MEASURES if m == "density" or m in first.measures]
            for criterion in first.criteria:
                shown = [m for m in measures if applies(m, criterion)]
                title = f"\ncriterion: {criterion} (summed over the common frames)" + (
                    GT_FREE_LABEL if criterion.startswith(GT_FREE_PREFIX) else ""
                )
                parts.append(
                    _criterion_block(title, sequence.scores, criterion, shown, first.relative)
                )
        if sequence.models is not None:
            parts.append("\n" + models_text(sequence.models, sequence.objectives))
    if summary.overall is not None:
        parts.append(f"\n=== all {len(summary.sequences)} sequences")
        parts.append(models_text(summary.overall, summary.overall_objectives))
    if problems:
        parts.append(
            wrapped(
                f"\n{len(problems)} problem(s) recorded (table 'problems'); "
                f"first: {problems[0].message}"
            )
        )
    return "\n".join(parts)
