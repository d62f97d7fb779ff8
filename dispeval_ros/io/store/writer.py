"""Writing a results database: creating or resuming a run's file, adding units in transactions."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TypeVar

from dispeval_ros.core.records import (
    FrameFlicker,
    FrameMotion,
    FramePair,
    FrameScores,
    FrameTiming,
    MatchCounts,
    PooledConfidence,
    Problem,
)
from dispeval_ros.errors import ConfigurationError, InputError, ResultsConflictError
from dispeval_ros.io.store.lock import _FolderLock
from dispeval_ros.io.store.reader import ResultsReader
from dispeval_ros.io.store.rows import PreparedUnit, prepare_unit
from dispeval_ros.io.store.schema import (
    _ADD_COUNTS,
    _BLOB,
    _INSERT_CONFIDENCE,
    _INSERT_DRIFT,
    _INSERT_FLICKER,
    _INSERT_MOTION,
    _INSERT_PAIR,
    _INSERT_TIMING,
    _PROVENANCE_TABLE,
    _SELECT_CONFIDENCE,
    _SELECT_DRIFT,
    _SELECT_FLICKER,
    _SELECT_MOTION,
    _SELECT_PAIRS,
    _SELECT_TIMING,
    CONFIDENCE_TABLE,
    DRIFT_TABLE,
    FAILED_MARK,
    FLICKER_TABLE,
    MOTION_TABLE,
    PAIRS_TABLE,
    RESULTS_FILE,
    TIMING_TABLE,
    _check_config,
    _clear,
    _config_rows,
    _connect,
    _holds_nothing,
    _initialise,
    _json,
    _Layout,
    _quote,
    _state,
    failure_record,
    has_table,
)

_Writer = TypeVar("_Writer", bound="ResultsWriter")


class ResultsWriter(ResultsReader):
    """The writing half of :class:`~dispeval_ros.io.store.ResultsStore`.

    Writers use :meth:`create` (one process, one connection, WAL journal). Use it from one
    thread at a time.
    """

    # -- opening -----------------------------------------------------------------------------

    @classmethod
    def create(
        cls: type[_Writer], directory: Path, config: Mapping[str, object], resume: bool = False
    ) -> _Writer:
        """Create ``directory/results.sqlite`` for a run, or continue it with ``resume``.

        Refuses to mix runs: existing results without ``resume`` and a different ``config``
        with it are configuration errors.
        """
        directory = Path(directory)
        wanted = _config_rows(config)
        try:
            directory.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise InputError(
                f"{directory}: cannot create the results folder ({error.strerror or error})"
            ) from None
        path = directory / RESULTS_FILE
        lock = _FolderLock.take(directory)
        try:
            connection = _connect(path, writable=True)
        except BaseException:
            lock.release()
            raise
        try:
            state = _state(connection, path)
            if state == "results" and _holds_nothing(connection):
                _clear(connection)  # a run that stopped before its first unit left no results
                state = "empty"
            if state == "results" and not resume:
                raise ResultsConflictError(f"{directory} already holds results", resumable=True)
            connection.execute("PRAGMA journal_mode = WAL")
            connection.execute("PRAGMA synchronous = NORMAL")
            if state == "empty":
                _initialise(connection, wanted)
            else:
                _check_config(connection, directory, wanted)
        except sqlite3.Error as error:
            connection.close()
            lock.release()
            raise InputError(f"{path}: cannot write the results database ({error})") from None
        except BaseException:
            connection.close()
            lock.release()
            raise
        return cls(connection, path, writable=True, lock=lock)

    # -- writing -----------------------------------------------------------------------------

    def is_done(self, sequence: str, unit: str) -> bool:
        """Whether a unit was completely written (a resumed run skips it)."""
        row = self._db.execute(
            "SELECT 1 FROM units WHERE sequence = ? AND unit = ?", (sequence, unit)
        ).fetchone()
        return row is not None

    def done_units(self, sequence: str) -> set[str]:
        """The units of a sequence that were completely written (failure records aside)."""
        rows = self._db.execute("SELECT unit FROM units WHERE sequence = ?", (sequence,))
        return {unit for (unit,) in rows if not unit.endswith(FAILED_MARK)}

    def failed_units(self, sequence: str) -> set[str]:
        """The units of a sequence whose last run failed every attempt (a resume retries them)."""
        rows = self._db.execute("SELECT unit FROM units WHERE sequence = ?", (sequence,))
        return {unit[: -len(FAILED_MARK)] for (unit,) in rows if unit.endswith(FAILED_MARK)}

    def add_unit(
        self,
        sequence: str,
        unit: str,
        frames: Sequence[FrameScores],
        problems: Sequence[Problem] = (),
        counts: Mapping[str, MatchCounts] | None = None,
        timing: Sequence[FrameTiming] = (),
        pairs: Sequence[FramePair] = (),
        motion: Sequence[FrameMotion] = (),
        flicker: Sequence[FrameFlicker] = (),
        confidence: Sequence[PooledConfidence] = (),
    ) -> None:
        """Write one unit of work in one transaction and mark it done; a done unit is a no-op.

        Frames, problems, arrival times and the added match counts are all-or-nothing, so a
        kill can never leave half a unit, and adding it again after a resume changes nothing.
        """
        self._require_writable()
        if self._written(sequence, unit, unit.endswith(FAILED_MARK)):
            return
        self.add_prepared(
            prepare_unit(
                sequence,
                unit,
                frames,
                problems,
                counts,
                timing,
                pairs,
                motion,
                flicker,
                confidence,
            )
        )

    def _written(self, sequence: str, unit: str, failure: bool) -> bool:
        """Whether writing ``unit`` is a no-op: it is done (a failure record: its unit is)."""
        return self.is_done(sequence, unit[: -len(FAILED_MARK)] if failure else unit)

    def add_prepared(self, prepared: PreparedUnit) -> None:
        """:meth:`add_unit` of rows made by :func:`prepare_unit` (e.g. on another machine)."""
        self._require_writable()
        sequence, unit, layout = prepared.sequence, prepared.unit, prepared.layout
        failure = unit.endswith(FAILED_MARK)
        if self._written(sequence, unit, failure):
            return
        frame_rows, methods, criteria = prepared.frame_rows, prepared.methods, prepared.criteria
        problem_rows, count_rows = prepared.problem_rows, prepared.count_rows
        with self._transaction():
            if self._written(sequence, unit, failure):  # again, now under the write lock
                return
            record = unit if failure else failure_record(unit)  # an earlier failure's record
            for table in ("problems", "units"):
                self._db.execute(
                    f"DELETE FROM {table} WHERE sequence = ? AND unit = ?", (sequence, record)
                )
            if layout is not None:
                self._use_layout(layout)
            self._register_sequence(sequence)
            self._db.executemany(
                "INSERT OR IGNORE INTO methods (name, ordinal) "
                "VALUES (?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM methods))",
                [(method,) for method in methods],
            )
            self._db.executemany(
                "INSERT OR IGNORE INTO criteria (name, ordinal, overlapping) "
                "VALUES (?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM criteria), ?)",
                list(criteria.items()),
            )
            if layout is not None:
                try:
                    self._db.executemany(layout.insert_frames(), frame_rows)
                except sqlite3.IntegrityError as error:
                    if "UNIQUE" not in str(error):
                        raise
                    raise ValueError(
                        f"unit '{unit}' of {sequence} holds a frame (stamp, method) that "
                        "another unit already stored"
                    ) from None
            self._db.executemany(
                "INSERT INTO problems (sequence, unit, position, stamp, method, message) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                problem_rows,
            )
            self._db.executemany(_ADD_COUNTS, count_rows)
            timing, pairs = prepared.timing_rows, prepared.pair_rows
            later_tables = (  # tables added after the first schema: an older database has none
                (self.records_timing(), _INSERT_TIMING, timing, "the arrival of an estimate"),
                (self.records_pairs(), _INSERT_PAIR, pairs, "a pair"),
                (self.records_motion(), _INSERT_MOTION, prepared.motion_rows, "a motion pair"),
                (self.records_drift(), _INSERT_DRIFT, prepared.drift_rows, "a drift pair"),
                (self.records_flicker(), _INSERT_FLICKER, prepared.flicker_rows, "a window"),
                (
                    self.records_confidence(),
                    _INSERT_CONFIDENCE,
                    prepared.confidence_rows,
                    "confidence sums",
                ),
            )
            for recorded, statement, rows, what in later_tables:
                if not (rows and recorded):
                    continue
                try:
                    self._db.executemany(statement, rows)
                except sqlite3.IntegrityError:
                    raise ValueError(
                        f"unit '{unit}' of {sequence} holds {what} (stamp, method) that another "
                        "unit already stored"
                    ) from None
            self._db.execute(
                "INSERT INTO units (sequence, unit, ordinal) "
                "VALUES (?, ?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM units))",
                (sequence, unit),
            )
        if self._layout is None:
            self._layout = self._read_layout()

    def add_results(self, other: ResultsReader) -> int:
        """Copy every unit of ``other`` (frames, problems, match counts) in one transaction.

        Returns the units added. Refuses (one line) results of another scoring layout, a
        sequence both hold from different bags, and a unit both hold (it would count twice).
        """
        self._require_writable()
        layout = other._current_layout()
        mine = set(self.sequences())
        units = other._db.execute("SELECT sequence, unit FROM units ORDER BY ordinal").fetchall()
        with self._transaction():
            if layout is not None:
                self._use_layout(layout)
            for sequence in other.sequences():
                source, info = other.sequence_info(sequence)
                if sequence in mine and self.sequence_info(sequence) != (source, info):
                    raise ConfigurationError(
                        f"{other.path}: sequence {sequence} comes from {source or 'elsewhere'}"
                        f", in {self.path} from {self.sequence_info(sequence)[0] or 'elsewhere'}"
                    )
                self._register_sequence(sequence)
                self._db.execute(
                    "UPDATE sequences SET source = ?, info = ? WHERE name = ?",
                    (source, _json(info, f"the metadata of sequence {sequence}"), sequence),
                )
            for sequence, unit in units:
                if self.is_done(sequence, unit):
                    raise ConfigurationError(
                        f"{other.path}: unit {unit} of sequence {sequence} is in {self.path} "
                        "already; merging it again would count it twice"
                    )
                self._db.execute(
                    "INSERT INTO units (sequence, unit, ordinal) "
                    "VALUES (?, ?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM units))",
                    (sequence, unit),
                )
            self._db.executemany(
                "INSERT OR IGNORE INTO methods (name, ordinal) "
                "VALUES (?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM methods))",
                [(method,) for method in other.methods()],
            )
            _, overlapping = other._criterion_order()
            self._db.executemany(
                "INSERT OR IGNORE INTO criteria (name, ordinal, overlapping) "
                "VALUES (?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM criteria), ?)",
                [(name, name in overlapping) for name in other.criteria()],
            )
            if layout is not None:
                columns = "sequence, stamp, method, criterion, n" + "".join(
                    f", {_quote(name)}" for name in layout.measures
                )
                try:
                    self._db.executemany(
                        layout.insert_frames(),
                        other._db.execute(f"SELECT {columns}, sums, relative FROM frames"),
                    )
                except sqlite3.IntegrityError:
                    raise ConfigurationError(
                        f"{other.path} holds frames (sequence, stamp, method) that {self.path} "
                        "holds already"
                    ) from None
            self._db.executemany(
                "INSERT INTO problems (sequence, unit, position, stamp, method, message) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                other._db.execute(
                    "SELECT sequence, unit, position, stamp, method, message FROM problems"
                ),
            )
            self._db.executemany(
                _ADD_COUNTS,
                other._db.execute(
                    "SELECT sequence, method, sequence, matched, unmatched, dropped, failed "
                    "FROM match_counts ORDER BY sequence, ordinal"
                ),
            )
            for table, insert, select, what in (
                (TIMING_TABLE, _INSERT_TIMING, _SELECT_TIMING, "arrival times"),
                (PAIRS_TABLE, _INSERT_PAIR, _SELECT_PAIRS, "pairs"),
                (MOTION_TABLE, _INSERT_MOTION, _SELECT_MOTION, "ego-motion pairs"),
                (DRIFT_TABLE, _INSERT_DRIFT, _SELECT_DRIFT, "drift pairs"),
                (FLICKER_TABLE, _INSERT_FLICKER, _SELECT_FLICKER, "flicker windows"),
                (CONFIDENCE_TABLE, _INSERT_CONFIDENCE, _SELECT_CONFIDENCE, "confidence sums"),
            ):
                self._add_later_table(other, table, insert, select, what)
        self._layout = self._read_layout()
        return len(units)

    def _add_later_table(
        self, other: ResultsReader, table: str, insert: str, select: str, what: str
    ) -> None:
        """Copy ``other``'s rows of a table added later; results without it leave none."""
        if not has_table(self._db, table):
            return
        if not has_table(other._db, table):
            self._db.execute(f"DROP TABLE {table}")
            return
        try:
            self._db.executemany(insert, other._db.execute(select))
        except sqlite3.IntegrityError:
            raise ConfigurationError(
                f"{other.path} holds {what} (sequence, stamp, method) that {self.path} holds "
                "already"
            ) from None

    def set_sequence(self, sequence: str, source: str, info: Mapping[str, object]) -> None:
        """Record (or replace) a sequence's metadata: bag path, camera, topics, start/end."""
        self._require_writable()
        text = _json(info, f"the metadata of sequence {sequence}")
        with self._transaction():
            self._register_sequence(sequence)
            self._db.execute(
                "UPDATE sequences SET source = ?, info = ? WHERE name = ?", (source, text, sequence)
            )

    def set_provenance(self, record: Mapping[str, object]) -> None:
        """Record (or replace) how the results were made: version, configuration, input hashes.

        Kept in its own table (created on first use), one JSON value per key, so databases
        written before it existed stay readable.
        """
        self._require_writable()
        rows = _config_rows(record)
        with self._transaction():
            self._db.execute(_PROVENANCE_TABLE)
            self._db.executemany(
                "INSERT INTO provenance (key, value) VALUES (?, ?) "
                "ON CONFLICT(key) DO UPDATE SET value = excluded.value",
                rows,
            )

    # -- internals ---------------------------------------------------------------------------

    @contextmanager
    def _transaction(self) -> Iterator[None]:
        """One write transaction: committed if the block ends, rolled back if it raises.

        A failing write (disk full, I/O error) is one line; what earlier transactions stored
        stays intact, so the run can be resumed once the cause is gone.
        """
        try:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                yield
            except BaseException:
                if self._db.in_transaction:
                    self._db.execute("ROLLBACK")
                raise
            self._db.execute("COMMIT")
        except sqlite3.OperationalError as error:
            if self._db.in_transaction:
                self._db.execute("ROLLBACK")
            raise InputError(
                f"{self.path}: cannot write the results ({error}); what was stored before is "
                "intact: resume the run once the cause is gone"
            ) from None

    def _require_writable(self) -> None:
        if not self._writable:
            raise ValueError(f"{self.path} was opened read-only")

    def _register_sequence(self, sequence: str) -> None:
        self._db.execute(
            "INSERT OR IGNORE INTO sequences (name, ordinal) "
            "VALUES (?, (SELECT COALESCE(MAX(ordinal), -1) + 1 FROM sequences))",
            (sequence,),
        )

    def _use_layout(self, layout: _Layout) -> None:
        """Fix the layout with the first frames (creating the frames table), else check it."""
        stored = self._read_layout()
        if stored is None:
            self._db.execute(
                "INSERT INTO layout (id, measures, fields, thresholds, policy) "
                "VALUES (1, ?, ?, ?, ?)",
                (
                    json.dumps(list(layout.measures)),
                    json.dumps(list(layout.fields)),
                    layout.thresholds.astype(_BLOB).tobytes(),
                    layout.policy,
                ),
            )
            self._db.execute(layout.frames_table())
            return
        difference = layout.difference(stored)
        if difference is not None:
            raise ResultsConflictError(
                f"{self.path}: these scores do not fit the stored results ({difference} stored)",
                resumable=False,
            )
