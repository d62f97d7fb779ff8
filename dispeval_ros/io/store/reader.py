"""Reading a results database: opening it read-only, its names, scores, counts and problems."""

from __future__ import annotations

import json
import math
import sqlite3
from collections.abc import Collection, Iterator, Mapping
from pathlib import Path
from types import TracebackType
from typing import TypeVar

import numpy as np

from dispeval_ros.core.confidence import ConfidenceSums
from dispeval_ros.core.egomotion import TemporalSums
from dispeval_ros.core.lidar_drift import DriftSums
from dispeval_ros.core.measures import Scores, quantile_level
from dispeval_ros.core.records import (
    FrameFlicker,
    FrameTiming,
    MatchCounts,
    PooledConfidence,
    Problem,
)
from dispeval_ros.core.temporal import PairScores
from dispeval_ros.errors import ConfigurationError, InputError
from dispeval_ros.io.store.confidence import confidence_series, read_confidence_sums
from dispeval_ros.io.store.flicker import flicker_series, read_flicker
from dispeval_ros.io.store.lock import _FolderLock
from dispeval_ros.io.store.pairs import (
    motion_series,
    pair_series,
    read_drift,
    read_motion,
    read_pairs,
)
from dispeval_ros.io.store.schema import (
    _BLOB,
    _FRAME_ORDER,
    _ORDERED_FRAMES,
    CONFIDENCE_TABLE,
    DRIFT_TABLE,
    FLICKER_TABLE,
    MOTION_TABLE,
    PAIRS_TABLE,
    RESULTS_FILE,
    TIMING_TABLE,
    _check_config,
    _check_tables,
    _config_rows,
    _connect,
    _holds_nothing,
    _Layout,
    _state,
    _where,
    damaged,
    has_table,
)

_Store = TypeVar("_Store", bound="ResultsReader")


class ResultsReader:
    """The reading half of :class:`~dispeval_ros.io.store.ResultsStore` (one connection).

    Readers use :meth:`open` (read-only); the writer's class adds ``create``. Use it from one
    thread at a time.
    """

    def __init__(
        self,
        connection: sqlite3.Connection,
        path: Path,
        writable: bool,
        lock: _FolderLock | None = None,
    ) -> None:
        self._db = connection
        self.path = path
        self._writable = writable
        self._lock = lock
        self._layout: _Layout | None = None

    @classmethod
    def open(cls: type[_Store], directory_or_file: Path) -> _Store:
        """Open existing results read-only (for summaries and reports)."""
        path = Path(directory_or_file)
        if path.is_dir():
            path = path / RESULTS_FILE
        if not path.is_file():
            raise InputError(
                f"{path}: no such file; expected a results folder or its {RESULTS_FILE} "
                "(written by 'dispeval bag' or the summarizer)"
            )
        connection = _connect(path, writable=False)
        try:
            if _state(connection, path) != "results":
                raise InputError(
                    f"{path} is an empty SQLite database; expected dispeval results "
                    f"({RESULTS_FILE} written by 'dispeval bag' or the summarizer)"
                )
            _check_tables(connection, path)
        except BaseException:
            connection.close()
            raise
        return cls(connection, path, writable=False)

    def verify(self) -> None:
        """Every page reads back (``PRAGMA quick_check``), else one line naming the file.

        :meth:`open` reads the header and the table list only; a file damaged further in
        would otherwise be copied (``merge``) as if whole and noticed by ``report`` alone.
        """
        try:
            found = [row[0] for row in self._db.execute("PRAGMA quick_check").fetchall()]
        except sqlite3.DatabaseError as error:
            found = [str(error)]
        if found != ["ok"]:
            raise damaged(self.path, found[0])

    def close(self) -> None:
        """Close the connection (a writer's WAL is checkpointed into the database file)."""
        self._db.close()
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def __enter__(self: _Store) -> _Store:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    # -- reading -----------------------------------------------------------------------------

    def provenance(self) -> dict[str, object]:
        """The record of :meth:`set_provenance` (empty for results written without one)."""
        exists = self._db.execute(
            "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'provenance'"
        ).fetchone()
        if not exists:
            return {}
        rows = self._db.execute("SELECT key, value FROM provenance ORDER BY rowid")
        return {key: json.loads(value) for key, value in rows}

    def holds_units(self) -> bool:
        """Whether any unit was written (a run that stopped before its first holds nothing)."""
        return not _holds_nothing(self._db)

    def check_resumable(self, config: Mapping[str, object]) -> None:
        """Refuse as :meth:`create` with ``resume`` would, without opening for writing.

        A front end that needs a transport or a scheduler first can refuse another
        configuration's results before it starts them.
        """
        _check_config(self._db, self.path.parent, _config_rows(config))

    def sequences(self) -> list[str]:
        """Sequence names in first-seen order."""
        return self._names("sequences")

    def methods(self) -> list[str]:
        """Names of the methods with stored frames, in first-seen order."""
        return self._names("methods")

    def criteria(self) -> list[str]:
        """Criterion names in first-seen order."""
        return self._names("criteria")

    def measures(self) -> list[str]:
        """The measure columns of the frames (empty until the first frame is stored)."""
        layout = self._current_layout()
        return list(layout.measures) if layout else []

    def config(self) -> dict[str, object]:
        """The run's configuration as given to :meth:`create` (after a JSON round trip)."""
        rows = self._db.execute("SELECT key, value FROM run ORDER BY ordinal")
        return {key: json.loads(value) for key, value in rows}

    def sequence_info(self, sequence: str) -> tuple[str, dict[str, object]]:
        """A sequence's source and metadata as given to :meth:`set_sequence` (else '' and {})."""
        row = self._db.execute(
            "SELECT source, info FROM sequences WHERE name = ?", (sequence,)
        ).fetchone()
        if row is None:
            raise KeyError(sequence)
        source, info = row
        return source or "", json.loads(info) if info else {}

    def frame_rows(
        self, sequence: str | None = None, method: str | None = None
    ) -> Iterator[dict[str, object]]:
        """Stored rows (sequence, stamp, method, criterion, n, measures…; NULL read as NaN).

        Ordered by sequence, stamp, method and criterion (first-seen orders).
        """
        layout = self._current_layout()
        if layout is None:
            return
        where, parameters = _where(sequence=sequence, method=method)
        cursor = self._db.execute(
            "SELECT f.sequence, f.stamp, f.method, f.criterion, f.n"
            + layout.measure_columns()
            + _ORDERED_FRAMES
            + where
            + _FRAME_ORDER,
            parameters,
        )
        keys = ("sequence", "stamp", "method", "criterion")
        for row in cursor:
            record: dict[str, object] = dict(zip(keys, row[:4], strict=True))
            for name, value in zip(("n", *layout.measures), row[4:], strict=True):
                record[name] = math.nan if value is None else value
            yield record

    def sequence_scores(
        self, sequence: str | None = None, stamps: Collection[int] | None = None
    ) -> dict[str, Scores]:
        """Per method, the scores summed over a sequence (all if None), optionally some stamps.

        Sums of the stored float64 sums in frame order, bit-identical to :meth:`Scores.combine`
        of the frames (a criterion absent from a frame adds nothing; metric and relative SZE
        do not mix); measures are recomputed from them, so means are never averaged.
        Quantiles are not summable and come out NaN.
        """
        layout = self._current_layout()
        if layout is None:
            return {}
        where, parameters = _where(sequence=sequence)
        cursor = self._db.execute(
            "SELECT f.method, f.criterion, f.stamp, f.relative, f.sums"
            + _ORDERED_FRAMES
            + where
            + _FRAME_ORDER,
            parameters,
        )
        wanted = None if stamps is None else {int(stamp) for stamp in stamps}
        groups: dict[tuple[str, str], int] = {}
        relative: dict[str, bool] = {}
        blobs: list[bytes] = []
        targets: list[int] = []
        for method, criterion, stamp, is_relative, blob in cursor:
            if wanted is not None and stamp not in wanted:
                continue
            targets.append(groups.setdefault((method, criterion), len(groups)))
            blobs.append(blob)
            if relative.setdefault(method, bool(is_relative)) != bool(is_relative):
                raise ConfigurationError(
                    f"{self.path}: cannot sum the scores of {method} over "
                    f"{sequence or 'all sequences'}: metric SZE (with a camera) and relative "
                    "SZE (without) are mixed"
                )
        if not blobs:
            return {}
        rows = self._sums(b"".join(blobs), layout)
        totals = np.zeros((len(groups), len(layout.fields)), dtype=np.float64)
        np.add.at(totals, np.array(targets, dtype=np.intp), rows)  # sequential, in frame order
        order, overlapping = self._criterion_order()
        result: dict[str, Scores] = {}
        for method, any_relative in relative.items():
            criteria = sorted((c for m, c in groups if m == method), key=order.__getitem__)
            result[method] = Scores(
                criteria=tuple(criteria),
                measures=layout.measures,
                sums=totals[[groups[method, c] for c in criteria]],
                thresholds=layout.thresholds.copy(),
                relative=any_relative,
                overlapping=tuple(c for c in criteria if c in overlapping),
                policy=layout.policy,
            )
        return result

    def frame_scores(self, sequence: str, stamp: int) -> dict[str, Scores]:
        """Per method, the scores of one frame as they were stored (quantiles included)."""
        layout = self._current_layout()
        if layout is None:
            return {}
        cursor = self._db.execute(
            "SELECT f.method, f.criterion, f.relative, f.sums"
            + layout.measure_columns()
            + _ORDERED_FRAMES
            + " WHERE f.sequence = ? AND f.stamp = ?"
            + _FRAME_ORDER,
            (sequence, int(stamp)),
        )
        quantiles = [(i, name) for i, name in enumerate(layout.measures) if quantile_level(name)]
        _, overlapping = self._criterion_order()
        criteria: dict[str, list[str]] = {}
        blobs: dict[str, list[bytes]] = {}
        quantile_values: dict[str, dict[str, dict[str, float]]] = {}
        relative: dict[str, bool] = {}
        for method, criterion, is_relative, blob, *values in cursor:
            criteria.setdefault(method, []).append(criterion)
            blobs.setdefault(method, []).append(blob)
            relative[method] = bool(is_relative)
            quantile_values.setdefault(method, {})
            if quantiles:
                quantile_values[method][criterion] = {
                    name: math.nan if values[i] is None else float(values[i])
                    for i, name in quantiles
                }
        return {
            method: Scores(
                criteria=tuple(names),
                measures=layout.measures,
                sums=self._sums(b"".join(blobs[method]), layout),
                thresholds=layout.thresholds.copy(),
                quantiles=quantile_values[method],
                relative=relative[method],
                overlapping=tuple(c for c in names if c in overlapping),
                policy=layout.policy,
            )
            for method, names in criteria.items()
        }

    def stamps(self, sequence: str) -> list[int]:
        """The stamps of a sequence with any stored frame, ascending."""
        if self._current_layout() is None:
            return []
        rows = self._db.execute(
            "SELECT DISTINCT stamp FROM frames WHERE sequence = ? ORDER BY stamp", (sequence,)
        )
        return [stamp for (stamp,) in rows]

    def common_stamps(self, sequence: str) -> list[int]:
        """The stamps where every method stored for the sequence has scores (fair comparison)."""
        if self._current_layout() is None:
            return []
        rows = self._db.execute(
            "SELECT stamp FROM frames WHERE sequence = ? GROUP BY stamp "
            "HAVING COUNT(DISTINCT method) = "
            "(SELECT COUNT(DISTINCT method) FROM frames WHERE sequence = ?) ORDER BY stamp",
            (sequence, sequence),
        )
        return [stamp for (stamp,) in rows]

    def match_counts(self, sequence: str) -> dict[str, MatchCounts]:
        """Per method, the match counts added up over the sequence's units."""
        rows = self._db.execute(
            "SELECT method, matched, unmatched, dropped, failed FROM match_counts "
            "WHERE sequence = ? ORDER BY ordinal",
            (sequence,),
        )
        return {method: MatchCounts(*counts) for method, *counts in rows}

    def records_timing(self) -> bool:
        """Whether arrival times are recorded (a database written before they were: no)."""
        return has_table(self._db, TIMING_TABLE)

    def timing(self, sequence: str) -> dict[str, list[FrameTiming]] | None:
        """Per method (first-seen order), its estimates' arrivals in arrival order.

        None: no latency recorded (a database written before arrival times were).
        """
        if not self.records_timing():
            return None
        rows = self._db.execute(
            "SELECT t.stamp, t.method, t.estimate_stamp, t.arrival FROM timing t "
            "LEFT JOIN methods m ON m.name = t.method WHERE t.sequence = ? "
            "ORDER BY COALESCE(m.ordinal, 1 << 62), t.method, t.arrival, t.stamp",
            (sequence,),
        )
        found: dict[str, list[FrameTiming]] = {}
        for stamp, method, sent, arrival in rows:
            found.setdefault(method, []).append(FrameTiming(sequence, stamp, method, sent, arrival))
        return found

    def records_pairs(self) -> bool:
        """Whether temporal pair sums can be stored (a database older than them: no)."""
        return has_table(self._db, PAIRS_TABLE)

    def pairs(self, sequence: str) -> dict[str, PairScores] | None:
        """Per method (the methods' order), the sequence's pairs pooled by their sums.

        None: not recorded (a database written before pairs were); empty: no pair stored.
        """
        if not self.records_pairs():
            return None
        return read_pairs(self._db, str(self.path), sequence, self._names("methods"))

    def records_motion(self) -> bool:
        """Whether ego-motion residuals can be stored (a database older than them: no)."""
        return has_table(self._db, MOTION_TABLE)

    def motion_pairs(self, sequence: str) -> dict[str, tuple[int, TemporalSums]] | None:
        """Per method: its ego-motion pairs in ``sequence``, their sums pooled (None: not kept)."""
        if not self.records_motion():
            return None
        return read_motion(self._db, str(self.path), sequence, self._names("methods"))

    def records_drift(self) -> bool:
        """Whether LiDAR drifts can be stored (a database older than them: no)."""
        return has_table(self._db, DRIFT_TABLE)

    def drift_pairs(self, sequence: str) -> dict[str, tuple[int, DriftSums]] | None:
        """Per method: its LiDAR drift pairs in ``sequence``, pooled (None: not recorded)."""
        if not self.records_drift():
            return None
        return read_drift(self._db, str(self.path), sequence, self._names("methods"))

    def pair_series(self, sequence: str) -> dict[str, list[tuple[int, PairScores]]] | None:
        """Per method, the sequence's pairs one by one (stamp, scores); None: not recorded."""
        if not self.records_pairs():
            return None
        return pair_series(self._db, str(self.path), sequence)

    def motion_series(self, sequence: str) -> dict[str, list[tuple[int, TemporalSums]]] | None:
        """Per method, its ego-motion residual pair by pair (stamp, sums); None: not kept."""
        if not self.records_motion():
            return None
        return motion_series(self._db, str(self.path), sequence)

    def records_flicker(self) -> bool:
        """Whether flicker windows can be stored (a database older than them: no)."""
        return has_table(self._db, FLICKER_TABLE)

    def flicker(self, sequence: str) -> dict[str, tuple[int, int, TemporalSums]] | None:
        """Per method: its windows in ``sequence``, their frames, their sums pooled (None: not kept)."""
        if not self.records_flicker():
            return None
        return read_flicker(self._db, str(self.path), sequence, self._names("methods"))

    def records_confidence(self) -> bool:
        """Whether confidence sums can be stored (a database older than them: no)."""
        return has_table(self._db, CONFIDENCE_TABLE)

    def confidence(self, sequence: str) -> dict[str, tuple[int, str, ConfidenceSums]] | None:
        """Per method with a confidence: its frames, preset and pooled sums; None: not kept."""
        if not self.records_confidence():
            return None
        return read_confidence_sums(self._db, str(self.path), sequence, self._names("methods"))

    def confidence_series(self, sequence: str) -> dict[str, list[PooledConfidence]] | None:
        """Per method, its units' pooled confidence sums one by one; None: not kept."""
        if not self.records_confidence():
            return None
        return confidence_series(self._db, str(self.path), sequence)

    def flicker_series(self, sequence: str) -> dict[str, list[FrameFlicker]] | None:
        """Per method, its flicker windows one by one; None: not kept."""
        if not self.records_flicker():
            return None
        return flicker_series(self._db, str(self.path), sequence)

    def problems(self, sequence: str | None = None) -> list[Problem]:
        """Recorded problems of one sequence (or all), in the order they were written."""
        where, parameters = _where(sequence=sequence, table="p")
        rows = self._db.execute(
            "SELECT p.sequence, p.stamp, p.method, p.message FROM problems p "
            "JOIN sequences s ON s.name = p.sequence "
            "JOIN units u ON u.sequence = p.sequence AND u.unit = p.unit"
            + where
            + " ORDER BY s.ordinal, u.ordinal, p.position",
            parameters,
        )
        return [Problem(*row) for row in rows]

    def overlapping_criteria(self) -> set[str]:
        """Criteria stored as overlapping (the legacy Middlebury ones), recorded on first write."""
        return self._criterion_order()[1]

    def _names(self, table: str) -> list[str]:
        return [name for (name,) in self._db.execute(f"SELECT name FROM {table} ORDER BY ordinal")]

    def _criterion_order(self) -> tuple[dict[str, int], set[str]]:
        rows = self._db.execute("SELECT name, ordinal, overlapping FROM criteria").fetchall()
        return {name: ordinal for name, ordinal, _ in rows}, {name for name, _, o in rows if o}

    def _read_layout(self) -> _Layout | None:
        row = self._db.execute(
            "SELECT measures, fields, thresholds, policy FROM layout WHERE id = 1"
        ).fetchone()
        if row is None:
            return None
        measures, fields, thresholds, policy = row
        return _Layout(
            measures=tuple(json.loads(measures)),
            fields=tuple(json.loads(fields)),
            thresholds=np.frombuffer(thresholds, dtype=_BLOB).astype(np.float64),
            policy=policy,
        )

    def _current_layout(self) -> _Layout | None:
        """The layout, read again while none is known (a writer may have stored it since)."""
        if self._layout is None:
            self._layout = self._read_layout()
        return self._layout

    def _sums(self, blob: bytes, layout: _Layout) -> np.ndarray:
        width = len(layout.fields)
        if len(blob) % (width * _BLOB.itemsize):
            raise InputError(
                f"{self.path}: a stored accumulator row is not {width} float64 values; "
                "the database is damaged"
            )
        return np.frombuffer(blob, dtype=_BLOB).astype(np.float64).reshape(-1, width)
