"""Exporting a results database: every frame row as CSV, and the names of a run's files."""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path

from dispeval_ros.errors import InputError
from dispeval_ros.io.store.reader import ResultsReader

FRAMES_CSV = "frames.csv"
"""Every frame row of a results folder as CSV (:meth:`CsvExport.export_csv`)."""
SUMMARY_JSON = "summary.json"
"""The summary and provenance of a results folder (written by the run that made it)."""
TIMING_JSON = "timing.json"
"""The latency and rate of a results folder in ros2_benchmark's result-JSON keys."""
TIMING_COLUMNS = ("estimate_stamp", "arrival", "delay_ms")
"""Last in every frames.csv row: the estimate's header stamp and arrival (ns, as ``stamp``)
and its delay, arrival − estimate stamp in ms; empty where no latency was recorded."""


class CsvExport(ResultsReader):
    """The CSV export of :class:`~dispeval_ros.io.store.ResultsStore` (reads only)."""

    def export_csv(self, path: Path) -> int:
        """Write every frame row to CSV (NaN as an empty cell, floats exact); rows written."""
        path = Path(path)
        layout = self._current_layout()
        measures = layout.measures if layout else ()
        partial = path.with_name(path.name + ".partial")
        written = 0
        try:
            with open(partial, "w", newline="", encoding="utf-8") as handle:
                writer = csv.writer(handle)
                writer.writerow(
                    ["sequence", "stamp", "method", "criterion", "n", *measures, *TIMING_COLUMNS]
                )
                arrivals = self._arrivals()
                for row in self.frame_rows():
                    key = (row["sequence"], row["stamp"], row["method"])
                    writer.writerow(
                        [row["sequence"], row["stamp"], row["method"], row["criterion"]]
                        + [_cell(row[name]) for name in ("n", *measures)]
                        + _timing_cells(arrivals.get(key))
                    )
                    written += 1
            os.replace(partial, path)
        except OSError as error:
            partial.unlink(missing_ok=True)
            raise InputError(
                f"{path}: cannot write the CSV file ({error.strerror or error})"
            ) from None
        return written

    # -- internals ---------------------------------------------------------------------------

    def _arrivals(self) -> dict[tuple[object, object, object], tuple[int, int]]:
        """(sequence, stamp, method) → (estimate stamp, arrival) of every recorded estimate."""
        if not self.records_timing():
            return {}
        rows = self._db.execute(
            "SELECT sequence, stamp, method, estimate_stamp, arrival FROM timing"
        )
        return {(seq, stamp, method): (sent, arrival) for seq, stamp, method, sent, arrival in rows}


def _timing_cells(entry: tuple[int, int] | None) -> list[str]:
    if entry is None:
        return ["", "", ""]
    sent, arrival = entry
    return [str(sent), str(arrival), repr((arrival - sent) / 1e6)]


def _cell(value: object) -> str:
    """A CSV cell: empty for NaN, ``repr`` for numbers so they read back exactly."""
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return str(value)
