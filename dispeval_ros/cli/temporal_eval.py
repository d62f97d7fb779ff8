"""``eval --scene DIR --temporal``: each method's frame-to-frame consistency over the scene.

The frames of a scene folder are a sequence: frame t and t + 1 with both estimates of a method
form a pair, scored by :class:`~dispeval_ros.core.temporal.TemporalScorer` (docs/method.md,
"Temporal measures"). Order and gaps come from the frames' numbers, so a pair is never formed
across a frame that is missing: a frame without the method's estimate, or a number not scored,
ends a run of pairs and is reported. A method's pairs are pooled by their sums (preset
``dispeval``), or per run and averaged weighted by frames (``dynamicstereo``: a run is a clip).
"""

from __future__ import annotations

import argparse
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dispeval_ros.cli.output import plural, wrapped
from dispeval_ros.cli.summary import pair_table
from dispeval_ros.core import registry
from dispeval_ros.core.evaluator import Evaluator, Reference
from dispeval_ros.core.kernels.temporal import PAIR_BAD
from dispeval_ros.core.temporal import (
    DEFAULT_PRESET,
    PRESETS,
    PairScores,
    PreparedEstimate,
    TemporalScorer,
    frame_weighted_mean,
    pair_unit,
)
from dispeval_ros.errors import ConfigurationError, DispevalError
from dispeval_ros.io.scene_frames import GT_SOURCE_TEXT

Estimates = Sequence[tuple[str, Path]]
"""A frame's estimates: method and file."""


def add_options(
    parser: argparse._ActionsContainer, scope: str = "with --scene of consecutive frames"
) -> None:
    """``--temporal [PRESET]`` (off by default: nothing changes without it).

    ``scope``: where the pairs come from, as the command's help says it (``eval`` and the
    stream commands share the option and its wording).
    """
    parser.add_argument(
        "--temporal",
        nargs="?",
        const=DEFAULT_PRESET,
        choices=tuple(PRESETS),
        default=None,
        metavar="PRESET",
        help=f"{scope}: also score each method's frame-to-frame "
        "consistency (tepe, tepe_r, tepe_bad_X) over its consecutive frame pairs, normalised "
        f"as preset {' or '.join(PRESETS)} (default {DEFAULT_PRESET}; docs/method.md)",
    )


def check_options(args: argparse.Namespace) -> None:
    """Refuse ``--temporal`` where there is no sequence of frames (one line)."""
    if args.temporal is None:
        return
    if args.protocol is not None:
        raise ConfigurationError(
            "--temporal does not apply with --protocol: a benchmark's protocol scores frames "
            "one by one (drop one of them)"
        )
    if args.scene is None:
        raise ConfigurationError(
            "--temporal scores the consecutive frames of a scene folder: give --scene DIR"
        )


@dataclass(frozen=True)
class Gap:
    """Frames of the scene a method's sequence of pairs does not cross."""

    method: str
    after: str | None
    """The frame before the gap (None: the method's first frame is not the scene's)."""
    before: str | None
    """The frame after it (None: the method's last frame is not the scene's)."""
    missing: tuple[str, ...]
    """Scored frames without this method's estimate."""
    unscored: int
    """Frame numbers in the gap that no method was scored on (not in the folder, or no
    estimate of any method)."""
    sources: tuple[str, str] | None = None
    """The GT sources of the frames around it, when they differ (a pair would compare two
    different references)."""

    def text(self) -> str:
        """``sgbm: no pair 0006 → 0008: no estimate of frame 0007``."""
        reasons = []
        if self.missing:
            reasons.append(f"no estimate of frame {', '.join(self.missing)}")
        if self.unscored:
            reasons.append(f"{plural(self.unscored, 'frame number')} between not scored")
        if self.sources is not None:
            reasons.append(
                f"the ground truth changes from {' to '.join(map(_source, self.sources))}"
            )
        if self.after is None or self.before is None:
            return f"{self.method}: {'; '.join(reasons)} (fewer pairs)"
        return f"{self.method}: no pair {self.after} → {self.before}: {'; '.join(reasons)}"

    def to_dict(self) -> dict[str, object]:
        """JSON: the frames around the gap, what is missing, the sentence."""
        return {
            "method": self.method,
            "after": self.after,
            "before": self.before,
            "missing": list(self.missing),
            "unscored": self.unscored,
            "gt_sources": None if self.sources is None else list(self.sources),
            "text": self.text(),
        }


@dataclass(frozen=True)
class Plan:
    """Which frame pairs each method is scored on: runs of consecutive frames (indices)."""

    preset: str
    frames: tuple[str, ...]
    runs: dict[str, list[list[int]]]
    files: dict[str, dict[int, Path]]
    gaps: tuple[Gap, ...]


def numbered(option: str, folder: Path, names: Sequence[str]) -> list[int]:
    """The frames' numbers, increasing in the scene's order (else one line naming ``option``)."""
    numbers = []
    for name in names:
        if not name.isdigit():
            raise ConfigurationError(
                f"{option}: frame {name} of {folder} is not numbered; consecutive frames are "
                "told by their numbers (e.g. 0006, 0007)"
            )
        numbers.append(int(name))
    for (a, m), (b, n) in itertools.pairwise(zip(names, numbers, strict=True)):
        if n <= m:
            raise ConfigurationError(
                f"{option}: frames {a} and {b} of {folder} are out of order (or the same number)"
            )
    return numbers


def _source(source: str) -> str:
    return GT_SOURCE_TEXT.get(source, source)


@dataclass(frozen=True)
class Runs:
    """Runs of frames ``step`` numbers apart (indices) per method, their files, the gaps."""

    frames: tuple[str, ...]
    runs: dict[str, list[list[int]]]
    files: dict[str, dict[int, Path]]
    gaps: tuple[Gap, ...]


def frame_runs(
    option: str,
    args: argparse.Namespace,
    frames: Sequence[tuple[str | None, str | None, Estimates]],
    step: int = 1,
) -> Runs:
    """Each method's runs of frames ``step`` numbers apart; one line if there is no pair.

    ``frames``: each scored frame's name, GT source and estimates, in the scene's order. With
    ``step`` k the frames fall into k classes by their number modulo k, each paired within
    itself: a run ends where a class's next frame is missing or its GT source changes.
    """
    names = [name or "" for name, _, _ in frames]
    sources = [source or "" for _, source, _ in frames]
    if len(names) < 2:
        chosen = " (--frame chose it)" if args.frame is not None else ""
        raise ConfigurationError(
            f"{option} scores pairs of consecutive frames, but one frame of {args.scene} is "
            f"scored ({names[0] if names else 'none'}){chosen}"
        )
    numbers = numbered(option, args.scene, names)
    files: dict[str, dict[int, Path]] = {}
    for index, (_, _, estimates) in enumerate(frames):
        for method, path in estimates:
            files.setdefault(method, {})[index] = path
    classes: dict[int, list[int]] = {}
    for index, number in enumerate(numbers):
        classes.setdefault(number % step, []).append(index)
    runs: dict[str, list[list[int]]] = {method: [] for method in files}
    gaps: list[Gap] = []
    for method, have in files.items():
        for scene in classes.values():
            indices = [i for i in scene if i in have]
            if not indices:
                gaps.append(Gap(method, None, None, tuple(names[i] for i in scene), 0))
                continue
            runs[method].append([indices[0]])
            if indices[0] > scene[0]:
                before = tuple(names[i] for i in scene if i < indices[0])
                gaps.append(Gap(method, None, names[indices[0]], before, 0))
            for a, b in itertools.pairwise(indices):
                changes = None if sources[a] == sources[b] else (sources[a], sources[b])
                if numbers[b] == numbers[a] + step and changes is None:
                    runs[method][-1].append(b)
                    continue
                missing = tuple(names[i] for i in scene if a < i < b)
                unscored = (numbers[b] - numbers[a]) // step - 1 - len(missing)
                gaps.append(Gap(method, names[a], names[b], missing, unscored, changes))
                runs[method].append([b])
            if indices[-1] < scene[-1]:
                after = tuple(names[i] for i in scene if i > indices[-1])
                gaps.append(Gap(method, names[indices[-1]], None, after, 0))
        runs[method].sort()
    if all(len(run) < 2 for method_runs in runs.values() for run in method_runs):
        apart = "consecutive frames" if step == 1 else f"frames {step} numbers apart"
        raise ConfigurationError(
            f"{option}: no method has estimates of two {apart} of {args.scene} "
            f"(frames scored: {', '.join(names)})"
        )
    return Runs(tuple(names), runs, files, tuple(gaps))


def plan(
    args: argparse.Namespace, frames: Sequence[tuple[str | None, str | None, Estimates]]
) -> Plan | None:
    """The pairs ``--temporal`` scores (None without it); one line if there are none.

    ``frames``: each scored frame's name, GT source and estimates, in the scene's order.
    """
    if args.temporal is None:
        return None
    found = frame_runs("--temporal", args, frames)
    return Plan(args.temporal, found.frames, found.runs, found.files, found.gaps)


@dataclass
class MethodTemporal:
    """One method's pair measures over the scene: runs of frames, the pooled scores."""

    runs: list[list[str]]
    pooled: PairScores | None
    """Every pair's sums added (None: the method has no pair)."""
    values: dict[str, dict[str, float]] | None
    """criterion → measure → value under the preset (``n_pair`` the pooled count)."""


@dataclass
class TemporalResult:
    """The ``--temporal`` results of every method: for the tables, the JSON and ``--out``."""

    plan: Plan
    scorer: TemporalScorer
    methods: dict[str, MethodTemporal]

    def to_dict(self) -> dict[str, object]:
        """The JSON ``temporal`` entry (also stored with ``--out``)."""
        measures = list(self.scorer.measures)
        return {
            "preset": self.scorer.preset.name,
            "normalisation": self.scorer.preset.description,
            "missing": self.scorer.evaluator.missing,
            "measures": measures,
            "thresholds": [t for t in self.scorer.thresholds.tolist() if math.isfinite(t)],
            "units": {name: pair_unit(name) for name in measures},
            "frames": list(self.plan.frames),
            "methods": {method: _method_dict(one) for method, one in self.methods.items()},
            "gaps": [gap.to_dict() for gap in self.plan.gaps],
        }

    def text(self) -> str:
        """A table (criterion, method, pixel pairs, measures), each method's runs, the gaps."""
        preset = self.scorer.preset
        frames = self.plan.frames
        lines = [
            wrapped(
                f"temporal consistency over frames {frames[0]}–{frames[-1]} (--temporal "
                f"{preset.name}: {preset.description}; missing estimates: "
                f"{self.scorer.evaluator.missing})"
            )
        ]
        scored = {m: one.values for m, one in self.methods.items() if one.values is not None}
        lines.append(pair_table(scored, self.scorer.measures))
        for method, result in self.methods.items():
            runs = "; ".join(
                run[0] if len(run) == 1 else f"{run[0]}–{run[-1]}" for run in result.runs
            )
            pairs = "no pair" if result.pooled is None else plural(result.pooled.pairs, "pair")
            lines.append(wrapped(f"{method}: {plural(len(result.runs), 'run')} ({runs}), {pairs}"))
        lines += [wrapped("gap: " + gap.text()) for gap in self.plan.gaps]
        return "\n".join(lines)


def _method_dict(one: MethodTemporal) -> dict[str, object]:
    """A method's JSON: pairs, runs (frame names), values, the pooled sums by criterion.

    The sums are those of the fields in use: the bad counts at δ and the ``thresholds``.
    """
    sums = None
    if one.pooled is not None:
        used = int(np.count_nonzero(np.isfinite(one.pooled.thresholds)))
        fields = registry.PAIR_SUM_FIELDS[: PAIR_BAD + used]
        sums = {
            criterion: dict(zip(fields, row.tolist(), strict=False))
            for criterion, row in zip(one.pooled.criteria, one.pooled.sums, strict=True)
        }
    return {
        "pairs": 0 if one.pooled is None else one.pooled.pairs,
        "runs": one.runs,
        "criteria": one.values,
        "sums": sums,
    }


def score(
    temporal: Plan | None,
    evaluator: Evaluator,
    references: Sequence[Reference | None],
    est_scale: float | None,
) -> TemporalResult | None:
    """Score every planned pair of every method (None without ``--temporal``)."""
    from dispeval_ros.io import read_disparity

    if temporal is None:
        return None
    scorer = TemporalScorer(evaluator, preset=temporal.preset)
    names = temporal.frames
    pairs: dict[str, dict[int, PairScores]] = {method: {} for method in temporal.runs}
    wanted = {
        index: [m for m, runs in temporal.runs.items() for run in runs if index in run[:-1]]
        for index in range(len(names) - 1)
    }
    cache: dict[str, tuple[int, PreparedEstimate]] = {}

    def estimate(method: str, index: int) -> PreparedEstimate:
        """Frame ``index``'s estimate, prepared once for both pairs it is in."""
        if method in cache and cache[method][0] == index:
            return cache[method][1]
        array = read_disparity(temporal.files[method][index], scale=est_scale)
        cache[method] = (index, scorer.prepare(array))
        return cache[method][1]

    for index, methods in wanted.items():
        if not methods:
            continue
        now, after = references[index], references[index + 1]
        if now is None or after is None:
            raise ConfigurationError("--temporal needs the ground truth of every frame")
        where = f"frames {names[index]} → {names[index + 1]}"
        try:
            pair = scorer.pair(now, after)
            for method in methods:
                first = estimate(method, index)
                pairs[method][index] = scorer.score(pair, first, estimate(method, index + 1))
        except DispevalError as error:
            raise type(error)(f"--temporal, {where}: {error}") from None
    return TemporalResult(
        temporal,
        scorer,
        {method: _pooled(temporal, method, pairs[method]) for method in temporal.runs},
    )


def _pooled(temporal: Plan, method: str, pairs: dict[int, PairScores]) -> MethodTemporal:
    """A method's pairs pooled (by sums), and its values under the preset."""
    runs = temporal.runs[method]
    named = [[temporal.frames[i] for i in run] for run in runs]
    if not pairs:
        return MethodTemporal(named, None, None)
    pooled = PairScores.combine([pairs[i] for i in sorted(pairs)])
    values = pooled.to_dict()
    if temporal.preset == "dynamicstereo":  # each run is a clip, clips weighted by frames
        clips = [PairScores.combine([pairs[i] for i in run[:-1]]) for run in runs if len(run) > 1]
        for criterion, averaged in frame_weighted_mean(clips).items():
            values[criterion].update(averaged)
    return MethodTemporal(named, pooled, values)
