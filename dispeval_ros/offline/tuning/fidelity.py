"""Multi-fidelity sweeps (``tune --fidelity R``): successive halving cut between A* groups.

Round r of R scores the surviving configurations on the first ⌈N·2^(r−R)⌉ of the N frames of
all scenes, taken in interleaved order (frame 0 of every scene, then frame 1 of every scene,
…): a scene folder with many frames grows frame by frame, a set of one-frame scenes (MiddEval3)
grows scene by scene, and the last round holds every frame. Each round computes only the frames
it adds, for its survivors, as units of the sweep's own database (``r1_000000``, …); the frames
of earlier rounds are read back. On the round's frames it computes the objectives the final
models use (:func:`~dispeval_ros.summary.objective_table`, restricted to the survivors and the
round's frames: the same per-sequence sums, so the last round's rows are a full sweep's rows)
and keeps whole A* groups from group 1 on until at least a fraction ``keep`` of the round's
configurations is kept: a group is never split, so ties and near-ties survive together.

Every decision is a function of the stored rows, recomputed on ``--resume``: a killed run
resumed writes the units an uninterrupted run writes and makes the same cuts.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dispeval_ros.core import Evaluator, Scores, evaluate_models
from dispeval_ros.core.records import MatchCounts
from dispeval_ros.errors import ConfigurationError, InputError
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.tuning.space import Configuration
from dispeval_ros.offline.tuning.sweep import (
    DEFAULT_CHUNK,
    SceneFrame,
    SweepReport,
    plan,
    run_units,
    set_sequences,
)
from dispeval_ros.summary import objective_table

DEFAULT_KEEP = 0.5
"""The fraction of a round's configurations kept at least (whole A* groups, from group 1)."""


def round_stamps(frame_counts: Sequence[int], rounds: int) -> list[list[list[int]]]:
    """Per round, per scene, the stamps scored (interleaved order; the last round: all).

    One line if the scenes hold too few frames for ``rounds`` rounds that each add frames.
    """
    order = [
        (scene, stamp)
        for stamp in range(max(frame_counts, default=0))
        for scene, count in enumerate(frame_counts)
        if stamp < count
    ]
    total = len(order)
    sizes = _sizes(total, rounds)
    if not _growing(sizes):
        most = max((r for r in range(1, rounds) if _growing(_sizes(total, r))), default=1)
        raise ConfigurationError(
            f"--fidelity {rounds}: the scenes hold {total} frame(s) in all, too few for "
            f"{rounds} rounds that each add frames (at most {most})"
        )
    result = []
    for size in sizes:
        per_scene: list[list[int]] = [[] for _ in frame_counts]
        for scene, stamp in order[:size]:
            per_scene[scene].append(stamp)
        result.append(per_scene)
    return result


def _sizes(total: int, rounds: int) -> list[int]:
    return [-(-total // 2 ** (rounds - r)) for r in range(1, rounds + 1)]


def _growing(sizes: Sequence[int]) -> bool:
    return all(a < b for a, b in itertools.pairwise(sizes))


def keep_whole_groups(groups: Mapping[str, int], order: Sequence[str], keep: float) -> list[str]:
    """The names of the first whole A* groups holding at least ``keep`` of ``order`` (its order).

    At least two are kept (a model needs two methods) where there are two.
    """
    target = min(len(order), max(2, math.ceil(round(keep * len(order), 9))))
    kept: set[str] = set()
    for group in sorted({groups[name] for name in order}):
        if len(kept) >= target:
            break
        kept.update(name for name in order if groups[name] == group)
    return [name for name in order if name in kept]


class RoundView:
    """The database seen as a sweep of some configurations on some frames (a ScoreSource).

    ``stamps`` maps every sequence to the frames of the round; ``complete``: they are all of
    the scenes' frames (then the pooled scores over every sequence are the store's own).
    """

    def __init__(
        self,
        store: ResultsStore,
        methods: Sequence[str],
        stamps: Mapping[str, Sequence[int]],
        complete: bool = False,
    ):
        self.store = store
        self._methods = list(methods)
        self._stamps = {sequence: list(chosen) for sequence, chosen in stamps.items()}
        self.complete = complete
        for sequence in self.sequences():
            counts = store.match_counts(sequence)
            short = [
                m
                for m in self._methods
                if counts.get(m, MatchCounts(0, 0, 0, 0)).matched < len(self._stamps[sequence])
            ]
            if short:
                raise InputError(
                    f"{store.path}: sequence {sequence} lacks frames of configuration(s) "
                    f"{', '.join(short[:3])} that the round scored (a damaged database)"
                )

    def sequences(self) -> list[str]:
        """The sequences with frames in the round."""
        return [s for s in self.store.sequences() if self._stamps.get(s)]

    def methods(self) -> list[str]:
        """The configurations of the round."""
        return list(self._methods)

    def measures(self) -> list[str]:
        """The stored measures."""
        return self.store.measures()

    def common_stamps(self, sequence: str) -> list[int]:
        """The round's frames of ``sequence`` (every configuration of the round has them)."""
        return list(self._stamps.get(sequence, []))

    def _only(self, scores: Mapping[str, Any]) -> dict[str, Any]:
        return {m: scores[m] for m in self._methods if m in scores}

    def sequence_scores(
        self, sequence: str | None = None, stamps: Collection[int] | None = None
    ) -> dict[str, Scores]:
        """The store's sums, for the round's configurations and frames."""
        if sequence is None:
            if not self.complete or stamps is not None:
                parts = [self.sequence_scores(s, stamps) for s in self.sequences()]
                return {
                    m: Scores.combine([p[m] for p in parts if m in p])
                    for m in self._methods
                    if any(m in p for p in parts)
                }
            return self._only(self.store.sequence_scores())
        own = set(self._stamps.get(sequence, []))
        chosen = own if stamps is None else own & {int(s) for s in stamps}
        return self._only(self.store.sequence_scores(sequence, stamps=sorted(chosen)))

    def frame_scores(self, sequence: str, stamp: int) -> dict[str, Scores]:
        """The round's configurations' scores of one frame."""
        return self._only(self.store.frame_scores(sequence, stamp))

    def match_counts(self, sequence: str) -> dict[str, MatchCounts]:
        """The round's configurations' match counts (over the frames scored so far)."""
        return self._only(self.store.match_counts(sequence))

    def export_csv(self, path: Path) -> int:
        """Every stored row (the configurations cut in a round with the frames they had)."""
        return self.store.export_csv(path)

    def config(self) -> dict[str, object]:
        """The run's record."""
        return self.store.config()


@dataclass
class RoundReport:
    """One round: its frames, the configurations scored and kept, the compute it spent."""

    round: int
    frames: int
    configurations: int
    kept: int
    configuration_frames: int
    """Configuration-frames the round computes (its survivors on the frames it adds)."""
    seconds: float
    """Measured in this run (0 where a previous run had done the round)."""
    units_done: int
    units_skipped: int
    computed_now: int
    """Configuration-frames this run computed (less than the round's after a resume)."""
    cut: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        return dict(vars(self))


@dataclass
class FidelityReport:
    """Every round, and the compute of a full sweep of the same configurations and frames."""

    rounds: list[RoundReport]
    full_configuration_frames: int
    kept: list[str]
    view: RoundView

    @property
    def configuration_frames(self) -> int:
        """Configuration-frames of all rounds (each computed once)."""
        return sum(r.configuration_frames for r in self.rounds)

    @property
    def fraction(self) -> float:
        """The compute spent as a fraction of the full sweep's (configuration-frames)."""
        return self.configuration_frames / self.full_configuration_frames

    def full_seconds(self) -> float | None:
        """A full sweep's seconds at this run's measured rate (None: this run computed nothing)."""
        done = [r for r in self.rounds if r.units_done and not r.units_skipped]
        frames = sum(r.configuration_frames for r in done)
        if not frames:
            return None
        return sum(r.seconds for r in done) / frames * self.full_configuration_frames

    def sweep_report(self) -> SweepReport:
        """The rounds' units as one sweep's report (what the summary line says)."""
        return SweepReport(
            sum(r.units_done for r in self.rounds),
            sum(r.units_skipped for r in self.rounds),
            sum(r.computed_now for r in self.rounds),
        )

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form: the rounds, the compute against a full sweep's."""
        full = self.full_seconds()
        return {
            "rounds": [r.to_dict() for r in self.rounds],
            "configuration_frames": self.configuration_frames,
            "full_sweep_configuration_frames": self.full_configuration_frames,
            "compute_fraction": self.fraction,
            "seconds": sum(r.seconds for r in self.rounds),
            "full_sweep_seconds_estimate": full,
            "kept": self.kept,
        }


def run_fidelity(
    store: ResultsStore,
    scenes: Sequence[Path],
    loaded: Mapping[int, list[SceneFrame]],
    configurations: Sequence[Configuration],
    evaluator: Evaluator,
    rounds: int,
    keep: float = DEFAULT_KEEP,
    *,
    measures: Sequence[str] | None = None,
    granularity: str = "sequence",
    chunk: int = DEFAULT_CHUNK,
    jobs: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int, int, SweepReport], None] | None = None,
) -> FidelityReport:
    """Score ``configurations`` round by round, cutting whole A* groups (module docstring).

    ``measures`` and ``granularity``: the objectives, as the final models take them.
    """
    sequences = set_sequences(store, scenes, loaded)
    schedule = round_stamps([len(loaded[i]) for i in range(len(scenes))], rounds)
    survivors = list(configurations)
    previous: list[set[int]] = [set() for _ in scenes]
    reports = []
    view = None
    for number, stamps in enumerate(schedule, 1):
        added = [[s for s in chosen if s not in previous[i]] for i, chosen in enumerate(stamps)]
        units = plan(sequences, survivors, chunk, added, prefix=f"r{number}_")
        started = time.perf_counter()
        done = run_units(
            store,
            scenes,
            loaded,
            units,
            evaluator,
            jobs=jobs,
            scheduler=scheduler,
            progress=progress,
        )
        seconds = time.perf_counter() - started if done.units_done else 0.0
        names = [c.name for c in survivors]
        last = number == len(schedule)
        view = RoundView(store, names, dict(zip(sequences, stamps, strict=True)), complete=last)
        kept = names
        if not last:
            methods, _, matrix = objective_table(view, measures, granularity)
            kept = keep_whole_groups(evaluate_models(methods, matrix).groups, methods, keep)
        chosen = set(kept)
        reports.append(
            RoundReport(
                number,
                sum(map(len, stamps)),
                len(names),
                len(kept),
                len(names) * sum(map(len, added)),
                seconds,
                done.units_done,
                done.units_skipped,
                done.frames,
                [name for name in names if name not in chosen],
            )
        )
        survivors = [c for c in survivors if c.name in chosen]
        previous = [set(s) for s in stamps]
    assert view is not None  # at least two rounds (the options' check)
    full = len(configurations) * sum(len(loaded[i]) for i in range(len(scenes)))
    return FidelityReport(reports, full, [c.name for c in survivors], view)
