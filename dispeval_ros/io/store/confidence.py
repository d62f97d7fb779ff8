"""The ``confidence_sums`` table's rows: each method's confidence sums pooled over a unit.

Made with every new database (:mod:`~dispeval_ros.io.store.schema`); one written before it
reads as "confidence: not recorded". A row holds the parts of one
:class:`~dispeval_ros.core.confidence.ConfidenceSums` (float64 little-endian arrays, their
layout as JSON) and the preset the confidences were read in; a sequence's curves are those of
its rows added, exact.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from dispeval_ros.core.confidence import ConfidenceSums
from dispeval_ros.core.records import PooledConfidence
from dispeval_ros.errors import DispevalError, InputError
from dispeval_ros.io.store.pairs import _in_order
from dispeval_ros.io.store.schema import _BLOB

_ARRAYS = ("sums", "errors", "depth_errors", "counters", "points")


def confidence_rows(
    sequence: str, unit: str, pooled: Iterable[PooledConfidence]
) -> list[tuple[object, ...]]:
    """The ``confidence_sums`` rows of a unit's pooled sums (each of ``sequence``)."""
    rows: list[tuple[object, ...]] = []
    for entry in pooled:
        if entry.sequence != sequence:
            raise ValueError(f"unit '{unit}' of {sequence} holds confidence of {entry.sequence}")
        sums = entry.sums
        layout = {
            "criteria": list(sums.criteria),
            "thresholds": list(sums.thresholds),
            "levels": sums.levels,
            "depth": sums.depth,
        }
        blobs = [np.ascontiguousarray(getattr(sums, n), dtype=_BLOB).tobytes() for n in _ARRAYS]
        rows.append(
            (sequence, int(entry.start), entry.method, int(entry.stamp), int(entry.frames),
             entry.preset, json.dumps(layout), *blobs)
        )  # fmt: skip
    return rows


def restored_confidence(layout: Mapping[str, object], blobs: Sequence[bytes]) -> ConfidenceSums:
    """One row's sums from their stored parts (ValueError: they do not fit together)."""
    criteria = tuple(str(c) for c in layout["criteria"])  # type: ignore[attr-defined]
    thresholds = tuple(float(t) for t in layout["thresholds"])  # type: ignore[attr-defined]
    levels = int(layout["levels"])  # type: ignore[call-overload]
    cells = len(criteria)
    shapes = {
        "sums": (cells, levels + 1, 4 + len(thresholds)),
        "errors": (cells, -1, 2),
        "depth_errors": (cells, -1, 2),
        "counters": (cells, 3),
        "points": (cells,),
    }
    arrays = {}
    for name, blob in zip(_ARRAYS, blobs, strict=True):
        values = np.frombuffer(blob, dtype=_BLOB).astype(np.float64)
        arrays[name] = values.reshape(shapes[name])  # ValueError if the sizes disagree
    if arrays["errors"].shape != arrays["depth_errors"].shape:
        raise ValueError("the error bins of the two errors differ")
    return ConfidenceSums(criteria, thresholds, levels, bool(layout["depth"]), **arrays)


def confidence_series(
    connection: sqlite3.Connection, where: str, sequence: str
) -> dict[str, list[PooledConfidence]]:
    """Per method (first seen), its units' pooled sums by first stamp; ``where``: the database."""
    rows = connection.execute(
        "SELECT start, method, stamp, frames, preset, layout, sums, errors, depth_errors, "
        "counters, points FROM confidence_sums WHERE sequence = ? ORDER BY start",
        (sequence,),
    )
    found: dict[str, list[PooledConfidence]] = {}
    for start, method, stamp, frames, preset, layout, *blobs in rows:
        try:
            sums = restored_confidence(json.loads(layout), blobs)
        except (ValueError, KeyError, TypeError):
            raise InputError(f"{where}: a stored confidence row of {method} is damaged") from None
        found.setdefault(method, []).append(
            PooledConfidence(sequence, int(start), int(stamp), method, int(frames), preset, sums)
        )
    return found


def read_confidence_sums(
    connection: sqlite3.Connection, where: str, sequence: str, methods: Sequence[str]
) -> dict[str, tuple[int, str, ConfidenceSums]]:
    """Per method: its frames, its preset and its sums pooled over the sequence.

    Rows in two presets (a resumed run cannot mix them: its configuration is checked) or of
    other criteria are one line naming the database.
    """
    found = confidence_series(connection, where, sequence)
    pooled: dict[str, tuple[int, str, ConfidenceSums]] = {}
    for method in _in_order(found, methods):
        rows = found[method]
        presets = sorted({row.preset for row in rows})
        if len(presets) > 1:
            raise InputError(
                f"{where}: the confidence of {method} in {sequence} was read in presets "
                f"{', '.join(presets)}: their curves cannot be pooled"
            )
        try:
            sums = ConfidenceSums.pooled([row.sums for row in rows])
        except DispevalError as error:  # rows of other criteria, thresholds or levels
            raise InputError(f"{where}: {method} in {sequence}: {error}") from None
        pooled[method] = (sum(row.frames for row in rows), presets[0], sums)
    return pooled
