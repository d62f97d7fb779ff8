"""What the scoring tests share: the hand-worked example's maps and the one-line error check.

The example (GT 3×4, "." = invalid GT, est_range = (1, 50)) is worked out by hand in
test_scoring_measures.py; the criteria and error tests reuse its maps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

NAN = math.nan
INF = math.inf

GT_HAND = np.array([[2, 4, 8, 0], [10, 10, 10, 10], [5, NAN, 20, 40]], np.float32)
EST_HAND = np.array([[3, 4, 8, 7], [11.125, NAN, 10, 60], [5, 9, 16, 0]], np.float32)
RANGE_HAND = (1.0, 50.0)


def one_line(error: pytest.ExceptionInfo[BaseException]) -> str:
    """The error's message, checked to be a single non-empty line (what the CLI prints)."""
    message = str(error.value)
    assert message, "empty error message"
    assert "\n" not in message, f"multi-line message: {message!r}"
    return message
