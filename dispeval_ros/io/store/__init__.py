"""The results database of a run: per-frame scores, problems and match counts in SQLite.

``dispeval bag`` and the live summarizer write it one *unit* of work at a time (e.g. a time
slice of a bag); the HTML report reads it later. Each unit is one transaction that also marks
the unit done, so a killed run loses at most the unit being written, and a resumed run skips
the done units and ends with exactly the rows of an uninterrupted run. Every frame row keeps
its float64 accumulator row (``sums``), so sequence scores are exact sums of sums
(METHOD.md §4), never averages of per-frame means.

One module per job: ``schema`` (tables, header marks, opening checks), ``lock`` (one writing
run per folder), ``rows`` (a unit's rows, made without a database), ``reader``, ``writer`` and
``export`` (CSV). The records stored live in :mod:`dispeval_ros.core.records`.
"""

from __future__ import annotations

from dispeval_ros.core.records import FrameScores, FrameTiming, MatchCounts, Problem
from dispeval_ros.io.store.export import (
    FRAMES_CSV,
    SUMMARY_JSON,
    TIMING_COLUMNS,
    TIMING_JSON,
    CsvExport,
)
from dispeval_ros.io.store.reader import ResultsReader
from dispeval_ros.io.store.rows import PreparedUnit, prepare_unit
from dispeval_ros.io.store.schema import (
    APPLICATION_ID,
    FAILED_MARK,
    RESULTS_FILE,
    SCHEMA_VERSION,
    TIMING_TABLE,
    failure_record,
)
from dispeval_ros.io.store.writer import ResultsWriter

__all__ = [
    "APPLICATION_ID",
    "FAILED_MARK",
    "FRAMES_CSV",
    "RESULTS_FILE",
    "SCHEMA_VERSION",
    "SUMMARY_JSON",
    "TIMING_COLUMNS",
    "TIMING_JSON",
    "TIMING_TABLE",
    "FrameScores",
    "FrameTiming",
    "MatchCounts",
    "PreparedUnit",
    "Problem",
    "ResultsReader",
    "ResultsStore",
    "ResultsWriter",
    "failure_record",
    "prepare_unit",
]


class ResultsStore(ResultsWriter, CsvExport):
    """The results database of one run (``results.sqlite`` in the output folder).

    Writers use :meth:`create` (one process, one connection, WAL journal); readers use
    :meth:`open` (read-only). Use it from one thread at a time.
    """
