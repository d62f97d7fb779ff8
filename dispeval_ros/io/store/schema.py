"""The results database's schema and connection: tables, header marks, opening, checking.

What a file must hold to be dispeval results (application id, schema version, tables), the
scoring layout fixed by the first frame, and the canonical JSON every stored value is kept as.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path, PurePath

import numpy as np

from dispeval_ros.core.measures import SUM_FIELDS, Scores
from dispeval_ros.errors import ConfigurationError, InputError, ResultsConflictError

RESULTS_FILE = "results.sqlite"
APPLICATION_ID = 0x44737045
"""``"DspE"`` in the SQLite header: tells a dispeval results database from any other."""
SCHEMA_VERSION = 1
FAILED_MARK = "!failed"
"""Suffix of the record a unit that failed every attempt leaves (see :func:`failure_record`)."""
_BLOB = np.dtype("<f8")  # accumulator rows are stored little-endian whatever the machine
_FIXED_COLUMNS = ("sequence", "stamp", "method", "criterion", "n", "sums", "relative")

_SCHEMA = (
    # the run's configuration, one JSON value per key, in the caller's key order
    "CREATE TABLE run (key TEXT PRIMARY KEY, ordinal INTEGER NOT NULL UNIQUE, value TEXT NOT NULL)",
    # the scoring layout, fixed by the first frame: measure columns, sums fields, thresholds
    "CREATE TABLE layout (id INTEGER PRIMARY KEY CHECK (id = 1), measures TEXT NOT NULL, "
    "fields TEXT NOT NULL, thresholds BLOB NOT NULL, policy TEXT NOT NULL)",
    "CREATE TABLE sequences (name TEXT PRIMARY KEY, ordinal INTEGER NOT NULL UNIQUE, "
    "source TEXT, info TEXT)",
    "CREATE TABLE methods (name TEXT PRIMARY KEY, ordinal INTEGER NOT NULL UNIQUE)",
    "CREATE TABLE criteria (name TEXT PRIMARY KEY, ordinal INTEGER NOT NULL UNIQUE, "
    "overlapping INTEGER NOT NULL)",
    "CREATE TABLE units (sequence TEXT NOT NULL, unit TEXT NOT NULL, "
    "ordinal INTEGER NOT NULL UNIQUE, PRIMARY KEY (sequence, unit))",
    "CREATE TABLE problems (sequence TEXT NOT NULL, unit TEXT NOT NULL, position INTEGER NOT NULL, "
    "stamp INTEGER, method TEXT, message TEXT NOT NULL, PRIMARY KEY (sequence, unit, position))",
    "CREATE TABLE match_counts (sequence TEXT NOT NULL, method TEXT NOT NULL, "
    "ordinal INTEGER NOT NULL, matched INTEGER NOT NULL, unmatched INTEGER NOT NULL, "
    "dropped INTEGER NOT NULL, failed INTEGER NOT NULL, PRIMARY KEY (sequence, method))",
)


TIMING_TABLE = "timing"
_TIMING_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS timing (sequence TEXT NOT NULL, stamp INTEGER NOT NULL, "
    "method TEXT NOT NULL, estimate_stamp INTEGER NOT NULL, arrival INTEGER NOT NULL, "
    "PRIMARY KEY (sequence, stamp, method))"
)
"""When each method's estimate of a frame arrived (``stamp``: the GT frame's). Made with a new
database; one written before it existed has none and reads as "no latency recorded" (a run
resumed onto it records none either, so its latency is never that of a part of its frames)."""
_INSERT_TIMING = (
    "INSERT INTO timing (sequence, stamp, method, estimate_stamp, arrival) VALUES (?, ?, ?, ?, ?)"
)
_SELECT_TIMING = "SELECT sequence, stamp, method, estimate_stamp, arrival FROM timing"

PAIRS_TABLE = "pairs"
_PAIR_COLUMNS = "sequence, stamp, method, previous, criteria, thresholds, policy, preset, sums"
_PAIRS_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS pairs (sequence TEXT NOT NULL, stamp INTEGER NOT NULL, "
    "method TEXT NOT NULL, previous INTEGER NOT NULL, criteria TEXT NOT NULL, "
    "thresholds BLOB NOT NULL, policy TEXT NOT NULL, preset TEXT NOT NULL, "
    "sums BLOB NOT NULL, PRIMARY KEY (sequence, stamp, method))"
)
"""Each method's temporal pair sums (:mod:`~dispeval_ros.io.store.pairs`); ``stamp`` the later
frame's, ``previous`` the earlier's. Made with a new database, as ``timing``; one written before
it existed reads as "temporal: not recorded"."""
_INSERT_PAIR = f"INSERT INTO pairs ({_PAIR_COLUMNS}) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)"
_SELECT_PAIRS = f"SELECT {_PAIR_COLUMNS} FROM pairs"
MOTION_TABLE = "motion_pairs"
_MOTION_COLUMNS = "sequence, stamp, method, previous, criteria, thresholds, offset, sums"
_MOTION_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS motion_pairs (sequence TEXT NOT NULL, stamp INTEGER NOT NULL, "
    "method TEXT NOT NULL, previous INTEGER NOT NULL, criteria TEXT NOT NULL, "
    "thresholds BLOB NOT NULL, offset REAL NOT NULL, sums BLOB NOT NULL, "
    "PRIMARY KEY (sequence, stamp, method))"
)
"""Each method's ego-motion residual sums of a pair (``egomotion``), with the offset removed;
made with a new database as ``pairs``."""
_INSERT_MOTION = f"INSERT INTO motion_pairs ({_MOTION_COLUMNS}) VALUES (?, ?, ?, ?, ?, ?, ?, ?)"
_SELECT_MOTION = f"SELECT {_MOTION_COLUMNS} FROM motion_pairs"
DRIFT_TABLE = "drift_pairs"
_DRIFT_COLUMNS = "sequence, stamp, method, previous, criteria, thresholds, policy, visibility, sums"
_DRIFT_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS drift_pairs (sequence TEXT NOT NULL, stamp INTEGER NOT NULL, "
    "method TEXT NOT NULL, previous INTEGER NOT NULL, criteria TEXT NOT NULL, "
    "thresholds BLOB NOT NULL, policy TEXT NOT NULL, visibility TEXT NOT NULL, "
    "sums BLOB NOT NULL, PRIMARY KEY (sequence, stamp, method))"
)
"""Each method's LiDAR drift sums of an ego-motion pair (``egomotion`` with LiDAR GT), beside
``motion_pairs``; made with a new database as ``pairs`` (an older one reads as not recorded)."""
_INSERT_DRIFT = f"INSERT INTO drift_pairs ({_DRIFT_COLUMNS}) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)"
_SELECT_DRIFT = f"SELECT {_DRIFT_COLUMNS} FROM drift_pairs"
FLICKER_TABLE = "flicker_windows"
_FLICKER_COLUMNS = "sequence, start, method, stamp, frames, criteria, thresholds, sums"
_FLICKER_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS flicker_windows (sequence TEXT NOT NULL, start INTEGER NOT "
    "NULL, method TEXT NOT NULL, stamp INTEGER NOT NULL, frames INTEGER NOT NULL, criteria TEXT "
    "NOT NULL, thresholds BLOB NOT NULL, sums BLOB NOT NULL, PRIMARY KEY (sequence, start, method))"
)
"""Each method's flicker sums of a window (``flicker``), ``start`` and ``stamp`` its first and
last frames' stamps; made with a new database as ``pairs``."""
_INSERT_FLICKER = (
    f"INSERT INTO flicker_windows ({_FLICKER_COLUMNS}) VALUES (?, ?, ?, ?, ?, ?, ?, ?)"
)
_SELECT_FLICKER = f"SELECT {_FLICKER_COLUMNS} FROM flicker_windows"

CONFIDENCE_TABLE = "confidence_sums"
_CONFIDENCE_COLUMNS = (
    "sequence, start, method, stamp, frames, preset, layout, sums, errors, depth_errors, "
    "counters, points"
)
_CONFIDENCE_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS confidence_sums (sequence TEXT NOT NULL, start INTEGER NOT "
    "NULL, method TEXT NOT NULL, stamp INTEGER NOT NULL, frames INTEGER NOT NULL, preset TEXT "
    "NOT NULL, layout TEXT NOT NULL, sums BLOB NOT NULL, errors BLOB NOT NULL, depth_errors "
    "BLOB NOT NULL, counters BLOB NOT NULL, points BLOB NOT NULL, "
    "PRIMARY KEY (sequence, start, method))"
)
"""Each method's confidence sums pooled over a unit's frames (``confidences``), ``start``
and ``stamp`` its first and last frames' stamps; made with a new database as ``pairs``."""
_INSERT_CONFIDENCE = (
    f"INSERT INTO confidence_sums ({_CONFIDENCE_COLUMNS}) "
    "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)"
)
_SELECT_CONFIDENCE = f"SELECT {_CONFIDENCE_COLUMNS} FROM confidence_sums"


def has_table(connection: sqlite3.Connection, name: str) -> bool:
    """Whether the database holds table ``name`` (those added after the first schema)."""
    row = connection.execute(
        "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?", (name,)
    ).fetchone()
    return row is not None


def failure_record(unit: str) -> str:
    """The unit name under which a unit that failed every attempt is recorded.

    The record holds the failure's problem and no frames; the unit itself stays undone, so a
    resumed run tries it again, and writing it (or a newer failure) replaces the record.
    """
    return unit + FAILED_MARK


_ADD_COUNTS = (
    "INSERT INTO match_counts "
    "(sequence, method, ordinal, matched, unmatched, dropped, failed) VALUES (?, ?, "
    "(SELECT COALESCE(MAX(ordinal), -1) + 1 FROM match_counts WHERE sequence = ?), "
    "?, ?, ?, ?) ON CONFLICT (sequence, method) DO UPDATE SET "
    "matched = matched + excluded.matched, unmatched = unmatched + excluded.unmatched, "
    "dropped = dropped + excluded.dropped, failed = failed + excluded.failed"
)
"""Add a unit's match counts to its sequence's (rows: sequence, method, sequence, counts…)."""
_ORDERED_FRAMES = (
    " FROM frames f JOIN sequences s ON s.name = f.sequence JOIN methods m ON m.name = f.method"
    " JOIN criteria c ON c.name = f.criterion"
)
_FRAME_ORDER = " ORDER BY s.ordinal, f.stamp, m.ordinal, c.ordinal"


@dataclass(frozen=True)
class _Layout:
    """What every stored frame shares: measure columns, accumulator fields, thresholds, policy."""

    measures: tuple[str, ...]
    fields: tuple[str, ...]
    thresholds: np.ndarray
    policy: str

    @classmethod
    def of(cls, scores: Scores) -> _Layout:
        clash = [name for name in scores.measures if name in _FIXED_COLUMNS]
        if clash:
            raise ConfigurationError(f"measure name '{clash[0]}' is taken by a frames column")
        return cls(
            measures=tuple(scores.measures),
            fields=tuple(SUM_FIELDS),
            thresholds=np.asarray(scores.thresholds, dtype=np.float64),
            policy=scores.policy,
        )

    def difference(self, other: _Layout) -> str | None:
        """The first thing that differs, as 'what these vs those', or None."""
        pairs = (
            ("measures", ", ".join(self.measures), ", ".join(other.measures)),
            ("accumulator fields", ", ".join(self.fields), ", ".join(other.fields)),
            ("thresholds", _floats(self.thresholds), _floats(other.thresholds)),
            ("missing policy", self.policy, other.policy),
        )
        for what, mine, theirs in pairs:
            if mine != theirs:
                return f"{what} {mine} vs {theirs}"
        return None

    def frames_table(self) -> str:
        measures = "".join(f", {_quote(name)} REAL" for name in self.measures)
        return (
            "CREATE TABLE frames (sequence TEXT NOT NULL, stamp INTEGER NOT NULL, "
            f"method TEXT NOT NULL, criterion TEXT NOT NULL, n INTEGER{measures}, "
            "sums BLOB NOT NULL, relative INTEGER NOT NULL, "
            "PRIMARY KEY (sequence, stamp, method, criterion))"
        )

    def insert_frames(self) -> str:
        columns = ", ".join(["sequence", "stamp", "method", "criterion", "n"])
        measures = "".join(f", {_quote(name)}" for name in self.measures)
        marks = ", ".join("?" * (7 + len(self.measures)))
        return f"INSERT INTO frames ({columns}{measures}, sums, relative) VALUES ({marks})"

    def measure_columns(self) -> str:
        return "".join(f", f.{_quote(name)}" for name in self.measures)


_PROVENANCE_TABLE = (
    "CREATE TABLE IF NOT EXISTS provenance (key TEXT PRIMARY KEY, value TEXT NOT NULL)"
)


def _quote(name: str) -> str:
    """An SQL identifier for a measure name such as ``bad_0.5``."""
    return '"' + name.replace('"', '""') + '"'


def _floats(values: np.ndarray) -> str:
    return ", ".join(repr(float(v)) for v in values)


def _where(
    sequence: str | None = None, method: str | None = None, table: str = "f"
) -> tuple[str, tuple[str, ...]]:
    clauses, parameters = [], []
    for column, value in (("sequence", sequence), ("method", method)):
        if value is not None:
            clauses.append(f"{table}.{column} = ?")
            parameters.append(value)
    return (" WHERE " + " AND ".join(clauses) if clauses else ""), tuple(parameters)


def _jsonable(value: object) -> object:
    """What JSON cannot hold as such: arrays and numpy numbers, paths, sets."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, PurePath):
        return str(value)
    if isinstance(value, (set, frozenset)):
        return sorted(value, key=repr)
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")


def _json(value: object, what: str) -> str:
    """Canonical JSON (sorted keys, no spaces), so equal configurations compare equal as text."""
    try:
        return json.dumps(value, sort_keys=True, separators=(",", ":"), default=_jsonable)
    except (TypeError, ValueError) as error:
        raise ConfigurationError(f"{what} cannot be stored: {error}") from None


def _config_rows(config: Mapping[str, object]) -> list[tuple[str, str]]:
    return [
        (str(key), _json(value, f"configuration value '{key}'")) for key, value in config.items()
    ]


def damaged(path: Path, why: str) -> InputError:
    """The one line for a results file SQLite cannot read whole (``why``: what SQLite said)."""
    return InputError(
        f"{path}: the results database is damaged ({_shorten(' '.join(why.split()))}); "
        "it cannot be read whole"
    )


def _check_tables(connection: sqlite3.Connection, path: Path) -> None:
    """Every table of the schema is there (a damaged or hand-edited database is one line)."""
    try:
        present = {
            name
            for (name,) in connection.execute("SELECT name FROM sqlite_master WHERE type='table'")
        }
        layout = "layout" in present and connection.execute("SELECT COUNT(*) FROM layout")
        made = bool(layout and layout.fetchone()[0])  # made with the first frame
    except sqlite3.DatabaseError as error:
        raise damaged(path, str(error)) from None
    wanted = {statement.split()[2] for statement in _SCHEMA}
    if made:
        wanted.add("frames")
    missing = sorted(wanted - present)
    if missing:
        raise InputError(
            f"{path}: the results database is incomplete (no table {', '.join(missing)}); "
            "it was damaged or not written by dispeval"
        )


def _connect(path: Path, writable: bool) -> sqlite3.Connection:
    try:
        if writable:
            return sqlite3.connect(path, isolation_level=None, check_same_thread=False)
        return sqlite3.connect(
            path.resolve().as_uri() + "?mode=ro",
            uri=True,
            isolation_level=None,
            check_same_thread=False,
        )
    except sqlite3.Error as error:
        raise InputError(f"{path}: cannot open the results database ({error})") from None


def _state(connection: sqlite3.Connection, path: Path) -> str:
    """'results' (ours, this schema), 'empty' (a new file), else a one-line InputError."""
    try:
        application = connection.execute("PRAGMA application_id").fetchone()[0]
        version = connection.execute("PRAGMA user_version").fetchone()[0]
        tables = connection.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()[0]
    except sqlite3.DatabaseError as error:
        raise InputError(
            f"{path} is not a results database ({error}); expected an SQLite file "
            "written by 'dispeval bag' or the summarizer"
        ) from None
    if application == APPLICATION_ID:
        if version != SCHEMA_VERSION:
            raise InputError(
                f"{path} has results schema version {version}; this dispeval reads "
                f"version {SCHEMA_VERSION}"
            )
        return "results"
    if application == 0 and tables == 0:
        return "empty"
    raise InputError(
        f"{path} is an SQLite database but not dispeval results; expected {RESULTS_FILE} "
        "written by 'dispeval bag' or the summarizer"
    )


def _holds_nothing(connection: sqlite3.Connection) -> bool:
    """A results database no unit was ever written to (a run refused or killed at start)."""
    try:
        return connection.execute("SELECT COUNT(*) FROM units").fetchone()[0] == 0
    except sqlite3.DatabaseError:  # no units table: not ours to judge, _state said results
        return False


def _clear(connection: sqlite3.Connection) -> None:
    """Drop every table (and the provenance record), as before the first run."""
    tables = [
        name for (name,) in connection.execute("SELECT name FROM sqlite_master WHERE type='table'")
    ]
    connection.execute("BEGIN IMMEDIATE")
    try:
        for table in tables:
            connection.execute(f'DROP TABLE "{table}"')
        connection.execute("PRAGMA application_id = 0")
        connection.execute("PRAGMA user_version = 0")
    except BaseException:
        connection.execute("ROLLBACK")
        raise
    connection.execute("COMMIT")


def _initialise(connection: sqlite3.Connection, config: list[tuple[str, str]]) -> None:
    """Schema, configuration and header marks in one transaction (a kill leaves it empty)."""
    connection.execute("BEGIN IMMEDIATE")
    try:
        later = (
            _TIMING_SCHEMA, _PAIRS_SCHEMA, _MOTION_SCHEMA, _DRIFT_SCHEMA, _FLICKER_SCHEMA,
            _CONFIDENCE_SCHEMA,
        )  # fmt: skip
        for statement in (*_SCHEMA, *later):
            connection.execute(statement)
        connection.executemany(
            "INSERT INTO run (key, ordinal, value) VALUES (?, ?, ?)",
            [(key, ordinal, value) for ordinal, (key, value) in enumerate(config)],
        )
        connection.execute(f"PRAGMA application_id = {APPLICATION_ID}")
        connection.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
    except BaseException:
        connection.execute("ROLLBACK")
        raise
    connection.execute("COMMIT")


def _shorten(text: str, limit: int = 100) -> str:
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _check_config(
    connection: sqlite3.Connection, directory: Path, config: list[tuple[str, str]]
) -> None:
    """Resume only the same run: name the first key whose value differs."""
    stored = dict(connection.execute("SELECT key, value FROM run ORDER BY ordinal").fetchall())
    wanted = dict(config)
    for key in [*stored, *(key for key in wanted if key not in stored)]:
        old, new = stored.get(key), wanted.get(key)
        if old != new:
            raise ResultsConflictError(
                f"{directory} holds results of another configuration: '{key}' is "
                f"{_shorten(old or '(absent)')} there but {_shorten(new or '(absent)')} now",
                resumable=False,
            )
