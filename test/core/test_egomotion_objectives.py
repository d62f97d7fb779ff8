"""The ego-motion residual's objective measures: names, their values, refusals, ``--help``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dispeval_ros.core.egomotion import BASE_COLUMNS, TemporalSums
from dispeval_ros.core.objectives import (
    EGOMOTION_OBJECTIVES,
    egomotion_key,
    egomotion_objectives,
    split_egomotion_measures,
)
from dispeval_ros.errors import ConfigurationError


def sums(n: float, sum_abs: float, sum_sq: float, bad: float) -> TemporalSums:
    row = dict.fromkeys(BASE_COLUMNS, 0.0)
    row.update(n=n, n_residual=n, sum_abs=sum_abs, sum_sq=sum_sq)
    table = np.array([[*row.values(), bad], [0.0] * (len(BASE_COLUMNS) + 1)])
    return TemporalSums("egomotion", ("all", "edges"), (2.0,), table, (0.0,))


def test_names_map_to_the_residual_summary_keys() -> None:
    assert egomotion_key("egomotion_mean_abs") == "mean_abs"
    assert egomotion_key("egomotion_rms") == "rms"
    assert egomotion_key("egomotion_bad_2.0") == "bad_2"
    assert egomotion_key("egomotion_bad_X") is None  # the family, not a measure
    assert egomotion_key("egomotion_mean") is None  # signed: not a lower-is-better objective
    assert egomotion_key("tepe") is None
    assert split_egomotion_measures(["sze", "egomotion_rms"]) == (["sze"], ["egomotion_rms"])


def test_values_are_the_pooled_summary_on_gtfree_criteria_only_where_counted() -> None:
    motion = {"a": (2, sums(4, 2.0, 4.0, 1)), "b": (3, sums(10, 30.0, 160.0, 5))}
    names, block = egomotion_objectives(
        motion, "s", ["a", "b"], ["egomotion_mean_abs", "egomotion_rms", "egomotion_bad_2"]
    )
    assert names == [
        "gtfree:all/egomotion_mean_abs @s",
        "gtfree:all/egomotion_rms @s",
        "gtfree:all/egomotion_bad_2 @s",
    ]  # ``edges`` counted nothing: no objective
    np.testing.assert_array_equal(block, [[0.5, 1.0, 25.0], [3.0, 4.0, 50.0]])
    assert math.isclose(block[1, 1], motion["b"][1].summary("all")["rms"])


@pytest.mark.parametrize(
    ("motion", "measures", "words"),
    [
        (None, ["egomotion_rms"], "run with --egomotion"),
        ({"a": (1, sums(4, 2, 4, 1))}, ["egomotion_rms"], "b has no ego-motion pair"),
        (
            {"a": (1, sums(4, 2, 4, 1)), "b": (1, sums(4, 2, 4, 1))},
            ["egomotion_bad_1"],
            "scored at thresholds 2 px only",
        ),
        (
            {"a": (1, sums(4, 2, 4, 1)), "b": (1, sums(0, 0, 0, 0))},
            ["egomotion_rms"],
            "b has no residual counted",
        ),
    ],
)
def test_refusals_are_one_line(motion, measures, words) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigurationError, match=words) as caught:
        egomotion_objectives(motion, "s", ["a", "b"], measures)
    assert "\n" not in str(caught.value)


def test_help_lists_every_residual_objective(capsys: pytest.CaptureFixture[str]) -> None:
    from dispeval_ros.cli.main import main

    with pytest.raises(SystemExit):
        main(["bag", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for name, (_, meaning) in EGOMOTION_OBJECTIVES.items():
        assert f"{name} ({meaning})" in text
