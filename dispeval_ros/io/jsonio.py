"""Strict JSON for results: ``null`` for NaN/inf, numpy scalars as Python numbers."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any


def json_safe(value: Any) -> Any:
    """Recursively replace NaN/inf floats (not valid JSON) with None; numpy scalars to Python."""
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if hasattr(value, "item") and callable(value.item):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def dumps(document: Any) -> str:
    """Indented strict JSON; floats are written so they read back exactly."""
    return json.dumps(json_safe(document), indent=2, allow_nan=False)


def write_json(path: Path, document: Any) -> None:
    """Write :func:`dumps` of ``document`` to ``path`` (with a final newline)."""
    path.write_text(dumps(document) + "\n")
