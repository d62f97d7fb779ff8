"""The nodes' ROS parameters: descriptors, run-time alarms, ``ros2 param dump`` (needs ROS 2).

The harness and message builders: ros_nodes_support.py.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

from ros_nodes_support import (
    TIMEOUT,
    Parameter,
    Topics,
    rcl_interfaces,
)
from ros_support import Ros

from dispeval_ros.ros.params import (
    DOUBLE,
    EVALUATOR_PARAMETERS,
    INTEGER,
    SUMMARIZER_PARAMETERS,
    Param,
)


def descriptor_type(param: Param) -> int:
    types = rcl_interfaces.ParameterType
    return {
        "bool": types.PARAMETER_BOOL,
        "integer": types.PARAMETER_INTEGER,
        "double": types.PARAMETER_DOUBLE,
        "string": types.PARAMETER_STRING,
        "string[]": types.PARAMETER_STRING_ARRAY,
    }[param.kind]


def check_descriptors(node: Any, table: tuple[Param, ...]) -> None:
    for param in table:
        descriptor = node.describe_parameter(param.name)
        assert descriptor.description == param.description
        assert descriptor.additional_constraints == param.constraints
        assert descriptor.read_only == param.read_only
        assert descriptor.type == descriptor_type(param)
        if param.low is not None:
            ranges = (
                descriptor.floating_point_range
                if param.kind == DOUBLE
                else descriptor.integer_range
            )
            assert param.kind in (DOUBLE, INTEGER)
            assert len(ranges) == 1
            assert (ranges[0].from_value, ranges[0].to_value) == (param.low, param.high)


def test_parameters_have_descriptors_and_alarms_change_at_run_time(ros: Ros) -> None:
    topics = Topics("params")
    node = ros.evaluator(methods=[f"good:{topics.good}"], gt_topic=topics.gt)
    check_descriptors(node, EVALUATOR_PARAMETERS)
    assert node.get_parameter("queue_size").value == 4
    assert list(node.get_parameter("criteria").value) == ["all", "visibility", "depth"]
    assert node.config.methods == {"good": topics.good}
    assert node.config.measures is None  # [default]: the core's default for the GT kind

    (refused,) = node.set_parameters([Parameter("gt_topic", value="/elsewhere")])
    assert not refused.successful  # read-only
    (bad,) = node.set_parameters([Parameter("alarm_warn", value=["bmp"])])
    assert not bad.successful
    assert "CRITERION/MEASURE" in bad.reason
    (good,) = node.set_parameters([Parameter("alarm_warn", value=["all/bmp=0"])])
    assert good.successful


def parameter_values(ros: Ros, node_name: str) -> dict[str, Any]:
    """What ``ros2 param dump`` reads: ListParameters, then GetParameters of every name."""
    services = importlib.import_module("rcl_interfaces.srv")
    lister = ros.helper.create_client(services.ListParameters, f"/{node_name}/list_parameters")
    getter = ros.helper.create_client(services.GetParameters, f"/{node_name}/get_parameters")
    assert lister.wait_for_service(timeout_sec=TIMEOUT)
    assert getter.wait_for_service(timeout_sec=TIMEOUT)
    listed = lister.call_async(services.ListParameters.Request())
    assert ros.spin_until(listed.done)
    names = list(listed.result().result.names)
    got = getter.call_async(services.GetParameters.Request(names=names))
    assert ros.spin_until(got.done)
    values = list(got.result().values)
    assert len(values) == len(names), "GetParameters answered nothing: a parameter is unset"
    return {
        name: Parameter.from_parameter_msg(rcl_interfaces.Parameter(name=name, value=value))
        for name, value in zip(names, values, strict=True)
    }


def test_param_dump_answers_every_parameter(ros: Ros, tmp_path: Path) -> None:
    topics = Topics("dump")
    ros.evaluator(methods=[f"good:{topics.good}"], gt_topic=topics.gt)
    ros.summarizer(output_dir=str(tmp_path / "out"))
    for node_name, table in (
        ("dispeval_evaluator", EVALUATOR_PARAMETERS),
        ("dispeval_summarizer", SUMMARIZER_PARAMETERS),
    ):
        values = parameter_values(ros, node_name)
        for param in table:
            assert values[param.name].type_ != Parameter.Type.NOT_SET, param.name
    evaluator_values = parameter_values(ros, "dispeval_evaluator")
    assert list(evaluator_values["measures"].value) == ["default"]
    assert evaluator_values["alarm_warn"].type_ == Parameter.Type.STRING_ARRAY
    assert list(evaluator_values["alarm_warn"].value) == []
    assert list(evaluator_values["methods"].value) == [f"good:{topics.good}"]


def test_empty_array_defaults_are_never_read_only() -> None:
    """A typed empty value is set after declaring; ROS refuses that for read-only ones."""
    for param in (*EVALUATOR_PARAMETERS, *SUMMARIZER_PARAMETERS):
        if param.default == ():
            assert not param.read_only, param.name


def test_summarizer_parameters_have_descriptors(ros: Ros, tmp_path: Path) -> None:
    node = ros.summarizer(output_dir=str(tmp_path / "out"))
    check_descriptors(node, SUMMARIZER_PARAMETERS)
    assert node.options.config.out == tmp_path / "out"
