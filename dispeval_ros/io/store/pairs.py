"""The ``pairs`` table's rows: each method's temporal pair sums of two consecutive frames.

The table is made with every new database (:mod:`~dispeval_ros.io.store.schema`). A row holds
one pair's accumulator sums (criteria × pair fields, float64 little-endian) with what they need
to be read back as :class:`~dispeval_ros.core.temporal.PairScores`: criteria, thresholds,
policy and preset. A sequence's pair measures are its rows' sums added
(:meth:`PairScores.combine`), exact.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable, Mapping, Sequence
from functools import reduce
from operator import add

import numpy as np

from dispeval_ros.core.egomotion import TemporalSums
from dispeval_ros.core.lidar_drift import DriftSums
from dispeval_ros.core.records import FrameMotion, FramePair
from dispeval_ros.core.temporal import PairScores
from dispeval_ros.errors import ConfigurationError, InputError
from dispeval_ros.io.store.schema import _BLOB


def pair_rows(sequence: str, unit: str, pairs: Iterable[FramePair]) -> list[tuple[object, ...]]:
    """The ``pairs`` rows of a unit's pairs (each of ``sequence``)."""
    rows: list[tuple[object, ...]] = []
    for pair in pairs:
        if pair.sequence != sequence:
            raise ValueError(f"unit '{unit}' of {sequence} holds a pair of {pair.sequence}")
        scores = pair.scores
        rows.append(
            (
                sequence,
                int(pair.stamp),
                pair.method,
                int(pair.previous),
                json.dumps(list(scores.criteria)),
                np.ascontiguousarray(scores.thresholds, dtype=_BLOB).tobytes(),
                scores.policy,
                scores.preset.name,
                np.ascontiguousarray(scores.sums, dtype=_BLOB).tobytes(),
            )
        )
    return rows


def pair_series(
    connection: sqlite3.Connection, where: str, sequence: str
) -> dict[str, list[tuple[int, PairScores]]]:
    """Per method (first seen), the sequence's pairs one by one: (stamp, scores), by stamp.

    ``where``: the database's path, for the one line a damaged row gives.
    """
    rows = connection.execute(
        "SELECT stamp, method, criteria, thresholds, policy, preset, sums FROM pairs "
        "WHERE sequence = ? ORDER BY stamp",
        (sequence,),
    )
    found: dict[str, list[tuple[int, PairScores]]] = {}
    for stamp, method, criteria, thresholds, policy, preset, blob in rows:
        try:
            scores = PairScores.restored(
                json.loads(criteria),
                np.frombuffer(blob, dtype=_BLOB),
                np.frombuffer(thresholds, dtype=_BLOB),
                policy,
                preset,
            )
        except ValueError:
            raise InputError(f"{where}: a stored pair row of {method} is damaged") from None
        found.setdefault(method, []).append((int(stamp), scores))
    return found


def read_pairs(
    connection: sqlite3.Connection, where: str, sequence: str, methods: Sequence[str]
) -> dict[str, PairScores]:
    """Per method (in ``methods``' order, then first seen), the sequence's pairs pooled."""
    found = pair_series(connection, where, sequence)
    return {m: PairScores.combine([p for _, p in found[m]]) for m in _in_order(found, methods)}


def motion_rows(sequence: str, unit: str, pairs: Iterable[FrameMotion]) -> list[tuple[object, ...]]:
    """The ``motion_pairs`` rows of a unit's ego-motion residuals (each of one pair)."""
    rows: list[tuple[object, ...]] = []
    for pair in pairs:
        if pair.sequence != sequence:
            raise ValueError(f"unit '{unit}' of {sequence} holds a pair of {pair.sequence}")
        sums = pair.sums
        if len(sums.offsets) != 1:
            raise ValueError(f"{pair.method} at {pair.stamp}: not the sums of one pair")
        rows.append(
            (
                sequence,
                int(pair.stamp),
                pair.method,
                int(pair.previous),
                json.dumps(list(sums.criteria)),
                np.asarray(sums.thresholds, dtype=_BLOB).tobytes(),
                float(sums.offsets[0]),
                np.ascontiguousarray(sums.sums, dtype=_BLOB).tobytes(),
            )
        )
    return rows


def motion_series(
    connection: sqlite3.Connection, where: str, sequence: str
) -> dict[str, list[tuple[int, TemporalSums]]]:
    """Per method (first seen), its ego-motion residual sums pair by pair: (stamp, sums)."""
    rows = connection.execute(
        "SELECT stamp, method, criteria, thresholds, offset, sums FROM motion_pairs "
        "WHERE sequence = ? ORDER BY stamp",
        (sequence,),
    )
    found: dict[str, list[tuple[int, TemporalSums]]] = {}
    for stamp, method, criteria, thresholds, offset, blob in rows:
        levels = np.frombuffer(thresholds, dtype=_BLOB).tolist()
        try:
            one = TemporalSums.of_pair(
                json.loads(criteria), levels, np.frombuffer(blob, dtype=_BLOB), offset
            )
        except ValueError:
            raise InputError(f"{where}: a stored ego-motion row of {method} is damaged") from None
        found.setdefault(method, []).append((int(stamp), one))
    return found


def read_motion(
    connection: sqlite3.Connection, where: str, sequence: str, methods: Sequence[str]
) -> dict[str, tuple[int, TemporalSums]]:
    """Per method: its pairs in the sequence and their ego-motion residual sums pooled."""
    found = motion_series(connection, where, sequence)
    return {
        m: (len(found[m]), reduce(add, [s for _, s in found[m]])) for m in _in_order(found, methods)
    }


def drift_rows(sequence: str, unit: str, pairs: Iterable[FrameMotion]) -> list[tuple[object, ...]]:
    """The ``drift_pairs`` rows of a unit's ego-motion pairs that carry a LiDAR drift.

    Each row holds the policy and visibility test it was scored under, so a reader gives the
    summary's options without the run's configuration.
    """
    rows: list[tuple[object, ...]] = []
    for pair in pairs:
        drift = pair.drift
        if drift is None:
            continue
        if pair.sequence != sequence:
            raise ValueError(f"unit '{unit}' of {sequence} holds a pair of {pair.sequence}")
        if drift.options is None:
            raise ValueError(f"{pair.method} at {pair.stamp}: a drift without its options")
        rows.append(
            (
                sequence,
                int(pair.stamp),
                pair.method,
                int(pair.previous),
                json.dumps(list(drift.criteria)),
                np.asarray(drift.thresholds, dtype=_BLOB).tobytes(),
                drift.options.missing,
                str(drift.options.visibility),
                np.ascontiguousarray(drift.sums, dtype=_BLOB).tobytes(),
            )
        )
    return rows


def read_drift(
    connection: sqlite3.Connection, where: str, sequence: str, methods: Sequence[str]
) -> dict[str, tuple[int, DriftSums]]:
    """Per method: its drift pairs in the sequence and their sums pooled (with their options).

    A row that does not read back, or rows of one method that cannot be pooled (other
    options or criteria), is one line naming the database.
    """
    rows = connection.execute(
        "SELECT method, criteria, thresholds, policy, visibility, sums FROM drift_pairs "
        "WHERE sequence = ? ORDER BY stamp",
        (sequence,),
    )
    found: dict[str, list[DriftSums]] = {}
    for method, criteria, thresholds, policy, visibility, blob in rows:
        levels = np.frombuffer(thresholds, dtype=_BLOB).tolist()
        try:
            one = DriftSums.restored(
                json.loads(criteria), np.frombuffer(blob, _BLOB), policy, visibility, levels
            )
        except ValueError:
            raise InputError(f"{where}: a stored drift row of {method} is damaged") from None
        found.setdefault(method, []).append(one)
    try:
        return {m: (len(found[m]), reduce(add, found[m])) for m in _in_order(found, methods)}
    except ConfigurationError as error:
        raise InputError(f"{where}, sequence {sequence}: {error}") from None


def _in_order(found: Mapping[str, object], methods: Sequence[str]) -> list[str]:
    """The methods ``found`` holds: in ``methods``' order, then the others as first seen."""
    return [m for m in methods if m in found] + [m for m in found if m not in methods]
