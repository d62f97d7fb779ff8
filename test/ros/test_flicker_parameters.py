"""The evaluator's ``flicker`` parameter (no ROS needed: parameter values), and its file."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from dispeval_ros.errors import ConfigurationError
from dispeval_ros.ros import param_table, params
from dispeval_ros.stream.flicker import FlickerStage


def values(**changes: Any) -> dict[str, Any]:
    table = {p.name: p.empty_default for p in param_table.EVALUATOR_PARAMETERS}
    table.update(methods=("sgbm:/sgbm",), gt_topic="/gt")
    table.update(changes)
    return table


def test_flicker_is_off_by_default_and_a_window_when_set() -> None:
    assert params.evaluator_options(values()).core.flicker == 0
    assert params.evaluator_options(values()).core.flicker_stage() is None
    core = params.evaluator_options(values(flicker=7)).core
    stage = core.flicker_stage()
    assert isinstance(stage, FlickerStage)
    assert (core.flicker, stage.size, stage.gap_ns) == (7, 7, core.pair_gap_ns)


def test_a_window_of_one_frame_is_one_line_naming_the_parameter() -> None:
    with pytest.raises(
        ConfigurationError, match=r"^parameter flicker must be 0 \(off\) or a window"
    ):
        params.evaluator_options(values(flicker=1))


def test_the_shipped_file_holds_the_default() -> None:
    shipped = Path(__file__).resolve().parents[2] / "config" / "evaluator.yaml"
    document = yaml.safe_load(shipped.read_text())
    (node,) = document.values()
    assert node["ros__parameters"]["flicker"] == 0
