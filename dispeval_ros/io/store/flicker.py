"""The ``flicker_windows`` table's rows: each method's flicker sums of one window of frames.

Made with every new database (:mod:`~dispeval_ros.io.store.schema`); one written before it
reads as "flicker: not recorded". A row holds one window's sums (criteria × the columns of
:class:`~dispeval_ros.core.egomotion.TemporalSums`, float64 little-endian) with its criteria
and thresholds; a sequence's flicker is its rows' sums added, exact.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable, Sequence
from functools import reduce
from operator import add

import numpy as np

from dispeval_ros.core.egomotion import BASE_COLUMNS, TemporalSums
from dispeval_ros.core.records import FrameFlicker
from dispeval_ros.errors import InputError
from dispeval_ros.io.store.pairs import _in_order
from dispeval_ros.io.store.schema import _BLOB


def flicker_rows(
    sequence: str, unit: str, windows: Iterable[FrameFlicker]
) -> list[tuple[object, ...]]:
    """The ``flicker_windows`` rows of a unit's windows (each of ``sequence``)."""
    rows: list[tuple[object, ...]] = []
    for window in windows:
        if window.sequence != sequence:
            raise ValueError(f"unit '{unit}' of {sequence} holds a window of {window.sequence}")
        sums = window.sums
        rows.append(
            (
                sequence,
                int(window.start),
                window.method,
                int(window.stamp),
                int(window.frames),
                json.dumps(list(sums.criteria)),
                np.asarray(sums.thresholds, dtype=_BLOB).tobytes(),
                np.ascontiguousarray(sums.sums, dtype=_BLOB).tobytes(),
            )
        )
    return rows


def restored_flicker(
    criteria: Sequence[str], thresholds: Sequence[float], sums: object
) -> TemporalSums:
    """One window's flicker sums from their stored parts (ValueError: they do not fit)."""
    names, levels = tuple(criteria), tuple(float(t) for t in thresholds)
    values = np.array(sums, dtype=np.float64)
    width = len(BASE_COLUMNS) + len(levels)
    if not names or values.size != len(names) * width:
        raise ValueError(f"{len(names)} criteria, {values.size} sums of {width} columns")
    return TemporalSums("flicker", names, levels, values.reshape(len(names), width))


def flicker_series(
    connection: sqlite3.Connection, where: str, sequence: str
) -> dict[str, list[FrameFlicker]]:
    """Per method (first seen), its windows by first stamp; ``where`` names the database."""
    rows = connection.execute(
        "SELECT start, method, stamp, frames, criteria, thresholds, sums FROM flicker_windows "
        "WHERE sequence = ? ORDER BY start",
        (sequence,),
    )
    found: dict[str, list[FrameFlicker]] = {}
    for start, method, stamp, frames, criteria, thresholds, blob in rows:
        try:
            sums = restored_flicker(
                json.loads(criteria),
                np.frombuffer(thresholds, dtype=_BLOB).tolist(),
                np.frombuffer(blob, dtype=_BLOB),
            )
        except ValueError:
            raise InputError(f"{where}: a stored flicker row of {method} is damaged") from None
        found.setdefault(method, []).append(
            FrameFlicker(sequence, int(start), int(stamp), method, int(frames), sums)
        )
    return found


def read_flicker(
    connection: sqlite3.Connection, where: str, sequence: str, methods: Sequence[str]
) -> dict[str, tuple[int, int, TemporalSums]]:
    """Per method: its windows, their frames and their flicker sums pooled."""
    found = flicker_series(connection, where, sequence)
    return {
        m: (
            len(found[m]),
            sum(w.frames for w in found[m]),
            reduce(add, [w.sums for w in found[m]]),
        )
        for m in _in_order(found, methods)
    }
