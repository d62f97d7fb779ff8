"""Objective tables in CSV: a ``method`` column and one numeric column per objective."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from dispeval_ros.errors import InputError

FRAMES_COLUMNS = ("sequence", "stamp", "method", "criterion", "n")
"""The first columns of a results folder's ``frames.csv``."""


def is_frames_csv(path: Path) -> bool:
    """Whether ``path`` is a ``frames.csv`` of stored results (by its header)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as handle:
            header = next(csv.reader(handle), [])
    except (OSError, UnicodeDecodeError):
        return False
    return tuple(cell.strip() for cell in header[: len(FRAMES_COLUMNS)]) == FRAMES_COLUMNS


def read_objectives_csv(path: Path) -> tuple[list[str], list[str], np.ndarray]:
    """Methods, objective names and the matrix of a scores CSV (empty cells are NaN)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as handle:
            rows = list(csv.reader(handle))
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(
            f"{path}: cannot read the CSV file ({error.__class__.__name__}: {error})"
        ) from None
    rows = [row for row in rows if any(cell.strip() for cell in row)]
    if not rows:
        raise InputError(f"{path}: the CSV file is empty; expected a header with a 'method' column")
    header = [cell.strip() for cell in rows[0]]
    if "method" not in header:
        raise InputError(f"{path}: no 'method' column in the header (found: {', '.join(header)})")
    method_column = header.index("method")
    objectives = [name for i, name in enumerate(header) if i != method_column]
    if not objectives:
        raise InputError(f"{path}: no objective column beside 'method'")
    methods: list[str] = []
    matrix = np.empty((len(rows) - 1, len(objectives)), dtype=np.float64)
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise InputError(
                f"{path}, line {line}: {len(row)} cells, expected {len(header)} as in the header"
            )
        methods.append(row[method_column].strip())
        values = [cell for i, cell in enumerate(row) if i != method_column]
        for column, cell in enumerate(values):
            text = cell.strip()
            try:
                matrix[line - 2, column] = float(text) if text else math.nan
            except ValueError:
                raise InputError(
                    f"{path}, line {line}, column '{objectives[column]}': expected a number, got '{text}'"
                ) from None
    if not methods:
        raise InputError(f"{path}: the CSV file has a header but no method rows")
    return methods, objectives, matrix


def write_objectives_csv(
    path: Path, methods: list[str], objectives: list[str], matrix: np.ndarray
) -> None:
    """Write a table readable by :func:`read_objectives_csv` (floats in round-trip form)."""
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["method", *objectives])
        for method, row in zip(methods, matrix, strict=True):
            writer.writerow([method, *(repr(float(v)) if math.isfinite(v) else "" for v in row)])
