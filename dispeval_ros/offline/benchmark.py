"""A whole benchmark in one call: every frame of a dataset tree, every method, the summary.

:func:`evaluate_benchmark` finds the frames of a ground-truth tree and each method's results
laid out as the benchmark expects (:mod:`dispeval_ros.io.benchmarks`), scores them with the
official protocol (:mod:`dispeval_ros.core.protocols`), combines the frames the benchmark's
way and compares the methods with the A* Groups over the protocol's objectives. The run
carries its provenance: project version, protocol record and hash, sha256 of every file read.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from dispeval_ros.core.models import ModelResult, evaluate_models
from dispeval_ros.core.protocols import (
    EXACT,
    FrameData,
    FrameResult,
    Protocol,
    evaluate_frame,
    get_protocol,
    moved_digits,
    objective_matrix,
    summarize_frames,
)
from dispeval_ros.core.provenance import provenance_record
from dispeval_ros.errors import ConfigurationError, DispevalError
from dispeval_ros.io.benchmarks import (
    BenchmarkFrame,
    discover,
    find_estimate,
    load_frame,
    read_estimate,
)
from dispeval_ros.io.provenance import file_sha256


@dataclass(frozen=True)
class MovedDigit:
    """A printed value the official float32 arithmetic changes (``exact``: float64)."""

    method: str
    frame: str
    region: str
    column: str
    official: float
    exact: float


@dataclass
class BenchmarkRun:
    """Everything one protocol run produced (``to_dict`` is its JSON)."""

    protocol: Protocol
    dataset: str
    frames: list[str]
    results: dict[str, list[FrameResult]]
    summary: dict[str, dict[str, dict[str, float]]]
    objectives: list[str] = field(default_factory=list)
    models: ModelResult | None = None
    provenance: dict[str, object] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)
    moved: list[MovedDigit] = field(default_factory=list)

    def notes(self) -> list[str]:
        """What could not be evaluated, once per distinct note."""
        return list(
            dict.fromkeys(
                note for frames in self.results.values() for f in frames for note in f.notes
            )
        )

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form (NaN for the JSON writer to turn into null)."""
        return {
            "protocol": self.protocol.name,
            "title": self.protocol.title,
            "dataset": self.dataset,
            "regions": list(self.protocol.regions),
            "columns": list(self.protocol.columns),
            "percent": list(self.protocol.percent),
            "summary_rule": self.protocol.summary,
            "float32": self.protocol.float32,
            "frames": self.frames,
            "methods": {
                method: {
                    "frames": [f.to_dict() for f in frames],
                    "summary": self.summary[method],
                }
                for method, frames in self.results.items()
            },
            "notes": self.notes(),
            "float32_moved_digits": [vars(m) for m in self.moved],
            "objectives": self.objectives,
            "models": self.models.to_dict() if self.models else None,
            "provenance": self.provenance,
        }


def _score_method(
    protocol: Protocol,
    frames: list[BenchmarkFrame],
    method: str,
    results_dir: Path | None,
    hashes: dict[str, str],
    loaded: dict[Path, FrameData],
) -> list[FrameResult]:
    scored = []
    for frame in frames:
        path = find_estimate(protocol, frame, method, results_dir)
        hashes.setdefault(str(path), file_sha256(path))
        if frame.gt not in loaded:
            loaded[frame.gt] = load_frame(frame)
        try:
            scored.append(evaluate_frame(protocol, loaded[frame.gt], read_estimate(path, protocol)))
        except DispevalError as error:
            message = str(error)
            raise type(error)(message if str(path) in message else f"{path}: {message}") from None
    return scored


def evaluate_frames(
    protocol: Protocol | str,
    frames: list[BenchmarkFrame],
    estimates: Mapping[str, Path | None],
    dataset: str,
) -> BenchmarkRun:
    """Score each method's results on ``frames`` (``None``: ``disp0NAME.pfm`` in the scenes)."""
    chosen = get_protocol(protocol) if isinstance(protocol, str) else protocol
    if not estimates:
        raise ConfigurationError("no method to evaluate")
    if not frames:
        raise ConfigurationError(f"{dataset}: no frame to evaluate")
    hashes: dict[str, str] = {}
    for frame in frames:
        for path in frame.files().values():
            hashes.setdefault(str(path), file_sha256(path))
    loaded: dict[Path, FrameData] = {}
    results = {
        method: _score_method(
            chosen, frames, method, None if where is None else Path(where), hashes, loaded
        )
        for method, where in estimates.items()
    }
    summary = {method: summarize_frames(chosen, scored) for method, scored in results.items()}
    moved = _moved_digits(chosen, results, summary)
    run = BenchmarkRun(
        protocol=chosen,
        dataset=dataset,
        frames=[f.name for f in frames],
        results=results,
        summary=summary,
        moved=moved,
    )
    if len(results) > 1:
        methods, names, matrix = objective_matrix(chosen, results)
        if names:
            run.objectives = names
            run.models = evaluate_models(methods, matrix)
    configuration = {
        "protocol": chosen.record(),
        "protocol_sha256": chosen.sha256(),
        "dataset": str(dataset),
        "methods": {m: None if w is None else str(w) for m, w in estimates.items()},
    }
    run.files = hashes
    run.provenance = provenance_record(configuration, {"files": hashes})
    return run


def _moved_digits(
    protocol: Protocol,
    results: Mapping[str, list[FrameResult]],
    summary: Mapping[str, dict[str, dict[str, float]]],
) -> list[MovedDigit]:
    """Every printed value (two decimals) that the tool's float32 arithmetic changes."""
    moved: list[MovedDigit] = []
    for method, frames in results.items():
        exact_frames = [f.exact for f in frames if f.exact is not None]
        pairs = [(f.frame, f.values, f.exact.values) for f in frames if f.exact is not None]
        if len(exact_frames) == len(frames):
            exact_summary = summarize_frames(protocol, exact_frames, EXACT)
            pairs.append(("summary", summary[method], exact_summary))
        for frame, official, exact in pairs:
            for region, column, have, want in moved_digits(protocol, official, exact):
                moved.append(MovedDigit(method, frame, region, column, have, want))
    return moved


def evaluate_benchmark(
    protocol: Protocol | str, dataset: Path, estimates: Mapping[str, Path | None]
) -> BenchmarkRun:
    """Every frame of the ground-truth tree ``dataset`` for each method.

    ``estimates`` maps a method name to its results folder (laid out as the benchmark
    expects, or a single file for a single-scene folder), or to ``None`` for results written
    into the scene folders as ``disp0NAME.pfm`` (the MiddEval3 SDK layout).
    """
    chosen = get_protocol(protocol) if isinstance(protocol, str) else protocol
    return evaluate_frames(chosen, discover(chosen, Path(dataset)), estimates, str(dataset))


def single_frame(
    gt: Path,
    *,
    gt_noc: Path | None = None,
    mask: Path | None = None,
    obj_map: Path | None = None,
    calib: Path | None = None,
) -> BenchmarkFrame:
    """A frame given by its files (``dispeval eval --protocol P --gt FILE``)."""
    return BenchmarkFrame(
        name=Path(gt).stem,
        folder=Path(gt).parent,
        gt=Path(gt),
        gt_noc=gt_noc,
        mask=mask,
        obj_map=obj_map,
        calib=calib,
        single=True,
    )
