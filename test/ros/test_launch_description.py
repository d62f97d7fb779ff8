"""The shipped launch files, evaluated without running them (needs launch_ros; colcon test).

``dispeval.launch.py bag:=…`` once started the replay before the summarizer subscribed and lost
frames in half of the launches: the evaluator it launches must wait for one subscriber.
"""

from __future__ import annotations

import importlib
import importlib.util
from pathlib import Path
from typing import Any

import pytest
from ros_support import launch_unavailable

LAUNCH_DIR = Path(__file__).resolve().parents[2] / "launch_scripts"
UNAVAILABLE = launch_unavailable()


def load_launch_file(name: str) -> Any:
    spec = importlib.util.spec_from_file_location(name.replace(".", "_"), LAUNCH_DIR / name)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def evaluated_parameters(node: Any, context: Any) -> list[Any]:
    """A launch_ros Node's parameters (files and dicts) with their substitutions performed."""
    utilities = importlib.import_module("launch_ros.utilities")
    return list(utilities.evaluate_parameters(context, node._Node__parameters))


@pytest.mark.parametrize("bag", ["/recordings/drive1", ""])
def test_the_evaluator_waits_for_the_summarizer(bag: str) -> None:
    if UNAVAILABLE is not None:
        pytest.skip(UNAVAILABLE)
    launch = importlib.import_module("launch")
    module = load_launch_file("dispeval.launch.py")
    context = launch.LaunchContext()
    context.launch_configurations.update(
        {"config": "e.yaml", "summarizer_config": "s.yaml", "bag": bag, "output_dir": ""}
    )
    evaluator, summarizer = module._nodes(context)
    parameters: dict[str, Any] = {}
    for item in evaluated_parameters(evaluator, context):
        if isinstance(item, dict):
            parameters.update(item)
    assert parameters["bag_wait_subscribers"] == 1
    assert parameters.get("bag", "") == bag
    assert evaluated_parameters(summarizer, context)
