"""Printing for the command line: aligned text tables and JSON with ``null`` for NaN."""

from __future__ import annotations

import math
import shutil
import sys
import textwrap
from collections.abc import Callable, Sequence
from typing import Any, TextIO, cast

from dispeval_ros.io.jsonio import dumps, json_safe  # noqa: F401 (json_safe re-exported)

WIDTH = 100
"""The widest line the command line prints (narrower on a narrower terminal, never below 80)."""
_FIXED_RANGE = (1e-3, 1e5)
"""Magnitudes written in fixed point (4 decimals); a column with any other is scientific."""


def text_width() -> int:
    """Columns to fit: the terminal's, clamped to [80, :data:`WIDTH`] (100 when not a terminal)."""
    return min(WIDTH, max(80, shutil.get_terminal_size((WIDTH, 24)).columns))


def wrapped(text: str, width: int | None = None, indent: str = "  ") -> str:
    """Each line of ``text`` wrapped at ``width``, continuation lines indented by ``indent``.

    Words are never cut (a long path stays whole, to be copied).
    """
    limit = width or text_width()
    return "\n".join(
        textwrap.fill(
            line, limit, subsequent_indent=indent, break_long_words=False, break_on_hyphens=False
        )
        or line
        for line in text.split("\n")
    )


def plural(count: int, noun: str) -> str:
    """``1 objective``, ``14 objectives``: a count and its noun, as English has it."""
    return f"{count} {noun}" + ("" if count == 1 else "s")


def _special(value: float) -> str | None:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return None


def _is_integer(value: float) -> bool:
    return float(value).is_integer() and abs(value) < 1e15


def _fixed(value: float) -> bool:
    low, high = _FIXED_RANGE
    return value == 0 or low <= abs(value) < high


def format_number(value: float) -> str:
    """Short human form: integers as integers, others with 4 significant decimals."""
    special = _special(value)
    if special is not None:
        return special
    if _is_integer(value):
        return str(int(value))
    return f"{value:.4f}" if _fixed(value) else f"{value:.4g}"


def column_format(values: Sequence[float]) -> Callable[[float], str]:
    """One format for a whole column, chosen from its finite values.

    Integers if every one is an integer; fixed point (4 decimals) if every one lies in
    ``[0.001, 1e5)`` (or is 0); else scientific with 4 significant digits for all, so that a
    column never mixes ``8.999e+05`` and ``47058.0248``.
    """
    finite = [float(v) for v in values if _special(v) is None]
    if all(_is_integer(v) for v in finite):
        style = "integer"
    elif all(_fixed(v) for v in finite):
        style = "{:.4f}"
    else:
        style = "{:.3e}"

    def written(value: float) -> str:
        special = _special(value)
        if special is not None:
            return special
        return str(int(value)) if style == "integer" else style.format(value)

    return written


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float))


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """Aligned plain-text table: text left-aligned, numbers right-aligned, one format a column."""
    numeric = [all(_is_number(row[i]) for row in rows) for i in range(len(header))]
    formats = [
        column_format([cast(float, row[i]) for row in rows if _is_number(row[i])])
        for i in range(len(header))
    ]
    cells = [[str(h) for h in header]]
    for row in rows:
        cells.append(
            [formats[i](cast(float, v)) if _is_number(v) else str(v) for i, v in enumerate(row)]
        )
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
