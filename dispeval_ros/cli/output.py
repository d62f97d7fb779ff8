"""Printing for the command line: aligned text tables and JSON with ``null`` for NaN."""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from typing import Any, TextIO

from dispeval_ros.io.jsonio import dumps, json_safe  # noqa: F401 (json_safe re-exported)


def format_number(value: float) -> str:
    """Short human form: integers as integers, others with 4 significant decimals."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if float(value).is_integer() and abs(value) < 1e15:
        return str(int(value))
    magnitude = abs(value)
    if magnitude >= 1e5 or magnitude < 1e-3:
        return f"{value:.4g}"
    return f"{value:.4f}"


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """Aligned plain-text table: text left-aligned, numbers right-aligned."""
    cells = [[str(h) for h in header]]
    for row in rows:
        cells.append([format_number(v) if isinstance(v, (int, float)) else str(v) for v in row])
    numeric = [all(isinstance(row[i], (int, float)) for row in rows) for i in range(len(header))]
    widths = [max(len(line[i]) for line in cells) for i in range(len(header))]
    lines = []
    for index, line in enumerate(cells):
        parts = [
            cell.rjust(width) if numeric[i] and index else cell.ljust(width)
            for i, (cell, width) in enumerate(zip(line, widths, strict=True))
        ]
        lines.append("  ".join(parts).rstrip())
        if index == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def print_json(document: Any, stream: TextIO | None = None) -> None:
    """Strict JSON (``null`` for undefined numbers), floats written so they read back exactly."""
    (stream or sys.stdout).write(dumps(document) + "\n")
