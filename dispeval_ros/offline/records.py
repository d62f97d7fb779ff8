"""What a run leaves beside its results database: provenance record, frames.csv, summary.json.

The provenance of a stream run (version, configuration and its hash, stream digests), and
:func:`write_run_files`, the one writer of a results folder's ``frames.csv`` and
``summary.json`` (``bag``, ``merge``, ``eval --out`` and ``demo`` leave the same files), and
:func:`write_scored_folder`, the results folder of frames scored in one go (``eval --out``).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from dispeval_ros.core.provenance import provenance_record
from dispeval_ros.core.records import FrameScores, MatchCounts
from dispeval_ros.errors import ConfigurationError, ResultsConflictError
from dispeval_ros.io.jsonio import write_json
from dispeval_ros.io.provenance import digests_to_damage
from dispeval_ros.io.store import FRAMES_CSV, RESULTS_FILE, SUMMARY_JSON, TIMING_JSON, ResultsStore
from dispeval_ros.offline.bag_eval import sequence_names
from dispeval_ros.offline.units import open_bag
from dispeval_ros.stream.core import CoreConfig
from dispeval_ros.summary import RunSummary, ScoreSource, summarize


def stream_topics(config: CoreConfig) -> list[str]:
    """Every topic the evaluation reads: :attr:`CoreConfig.topics`, the readers' own list.

    Ground truth, methods, camera infos, /tf_static, images and right views, so the provenance
    hashes every stream that was scored. The ground truth and the methods come first: the order
    the records have always listed them in.
    """
    return list(dict.fromkeys([config.gt_topic, *config.methods.values(), *config.topics]))


class BagStreams:
    """Each bag's scored streams and their digests (every scored message is read and hashed).

    Hashing reads as much as the evaluation, so ``dispeval bag`` runs :meth:`compute`
    alongside it (``evaluate_bags(..., alongside=streams.compute)``): the reads release the GIL
    and so do BLAKE3 and sha256, so it takes what the scoring leaves of the cores (BLAKE3
    needs about a quarter of sha256's CPU: see the README's ``dispeval bag`` table).
    """

    def __init__(self, bags: Sequence[Path], config: CoreConfig) -> None:
        self.topics = stream_topics(config)
        self.bags = list(zip(bags, sequence_names(bags), strict=True))
        self.sources = [open_bag(path) for path in bags]  # here: open_bag is not thread-safe
        self.streams: dict[str, Any] | None = None

    def compute(self) -> None:
        """Read and hash every scored message of every bag (up to any damage, as scored)."""
        self.streams = {}
        for (path, sequence), source in zip(self.bags, self.sources, strict=True):
            topics, damage = digests_to_damage(path, self.topics, source)
            record: dict[str, Any] = {"bag": str(path), "topics": topics}
            if damage is not None:
                record["read_up_to"] = damage
            self.streams[sequence] = record

    def record(self) -> dict[str, Any]:
        """Sequence → its bag and per-topic digests (computed now if not yet)."""
        if self.streams is None:
            self.compute()
        assert self.streams is not None
        return self.streams


def record_bag_provenance(
    store: ResultsStore,
    bags: Sequence[Path],
    configuration: Mapping[str, object],
    config: CoreConfig,
    streams: BagStreams | None = None,
) -> dict[str, object]:
    """Hash each bag's scored streams (unless ``streams`` did), store the record and return it.

    ``inputs.streams`` maps each sequence to its bag and, per topic, the digest (keyed by its
    algorithm) and the number of its serialized messages (see
    :func:`dispeval_ros.io.provenance.stream_digests`);
    for a bag damaged on the way (a recording killed mid-write), those of the messages before
    the damage and, under ``read_up_to``, where reading stopped: what was scored.
    """
    if streams is None:
        streams = BagStreams(bags, config)
    record = provenance_record(configuration, {"streams": streams.record()})
    store.set_provenance(record)
    return record


@dataclass(frozen=True)
class RunFiles:
    """What :func:`write_run_files` wrote: CSV rows, the summary, the ``summary.json`` document."""

    rows: int
    summary: RunSummary
    document: dict[str, Any]


class RunSource(ScoreSource, Protocol):
    """What the run's files are written from: a database, or a view of it (tune rounds)."""

    def export_csv(self, path: Path) -> int: ...  # noqa: D102


def write_run_files(
    store: RunSource,
    folder: Path,
    provenance: Mapping[str, object],
    measures: Sequence[str] | None = None,
    granularity: str = "sequence",
) -> RunFiles:
    """Write ``folder/frames.csv`` and ``folder/summary.json`` of ``store`` (the run's summary).

    Where latency was recorded, also ``folder/timing.json`` (:meth:`RunSummary.benchmark_document`).

    ``measures`` and ``granularity`` are those of :func:`~dispeval_ros.summary.summarize`;
    ``summary.json`` is the summary with the run's ``provenance`` record.
    """
    rows = store.export_csv(folder / FRAMES_CSV)
    summary = summarize(store, measures, granularity)
    document = {**summary.to_dict(), "provenance": dict(provenance)}
    write_json(folder / SUMMARY_JSON, document)
    timing = summary.benchmark_document()
    if timing:  # latency recorded: its ros2_benchmark-style export beside the summary
        write_json(folder / TIMING_JSON, timing)
    return RunFiles(rows, summary, document)


def _holds_results(folder: Path) -> ConfigurationError:
    return ConfigurationError(
        f"{folder} already holds results; choose another --out (a new results folder)"
    )


def check_new_results_folder(folder: Path) -> None:
    """Refuse (one line) a folder that already holds results, before any scoring is spent."""
    if (folder / RESULTS_FILE).exists():
        raise _holds_results(folder)


def write_scored_folder(
    folder: Path,
    sequence: str,
    source: str,
    info: Mapping[str, object],
    frames: Sequence[FrameScores],
    provenance: Mapping[str, Any],
) -> RunFiles:
    """A results folder of frames scored in one go (``eval --out``), laid out as a bag run's.

    One sequence, one unit holding every frame, each method matched on the frames it has;
    the configuration is the provenance's. ``frames.csv`` and ``summary.json`` as
    :func:`write_run_files` writes them. Refuses (one line) a folder that holds results.
    """
    configuration = provenance.get("configuration")
    counts = Counter(frame.method for frame in frames)
    try:
        store = ResultsStore.create(folder, dict(configuration or {}))
    except ResultsConflictError:
        raise _holds_results(folder) from None
    with store:
        store.set_sequence(sequence, source, info)
        store.add_unit(
            sequence,
            "000000",
            frames,
            counts={method: MatchCounts(n, 0, 0, 0) for method, n in counts.items()},
        )
        store.set_provenance(provenance)
        return write_run_files(store, folder, provenance)
