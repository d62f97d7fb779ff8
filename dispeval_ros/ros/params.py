"""The nodes' parameter values turned into configurations, and declared on a node.

The values read back are turned into :class:`~dispeval_ros.stream.core.CoreConfig` /
:class:`~dispeval_ros.stream.summarizer.SummarizerConfig` here; every user mistake is a
:class:`~dispeval_ros.errors.ConfigurationError` naming the parameter. The tables themselves are
in :mod:`dispeval_ros.ros.param_table`, the process life cycle in :mod:`dispeval_ros.ros.lifecycle`.

rclpy is imported inside the functions that need it only, so the tables and conversions import
(and can be checked) without ROS.
"""

from __future__ import annotations

import math
import os
import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dispeval_ros.errors import ConfigurationError, DispevalError, ResultsConflictError
from dispeval_ros.ros.param_table import (
    BOOL,
    DEFAULT_MEASURES_KEYWORD,
    DOUBLE,
    EVALUATOR_PARAMETERS,
    INTEGER,
    NS_PER_SECOND,
    STRING,
    STRING_ARRAY,
    SUMMARIZER_PARAMETERS,
    Param,
    ParamValue,
)
from dispeval_ros.stream.alarms import AlarmThresholds
from dispeval_ros.stream.config import FieldNames, core_default, refuse_live_confidences
from dispeval_ros.stream.core import CoreConfig
from dispeval_ros.stream.summarizer import SummarizerConfig
from dispeval_ros.stream.topics import NAMESPACE
from dispeval_ros.summary import GRANULARITIES

__all__ = [  # the table's names stay importable from here
    "BOOL",
    "DOUBLE",
    "EVALUATOR_PARAMETERS",
    "INTEGER",
    "ROS_NAMES",
    "STRING",
    "STRING_ARRAY",
    "SUMMARIZER_PARAMETERS",
    "EvaluatorOptions",
    "Param",
    "SummarizerOptions",
    "core_config",
    "declare_parameters",
    "default_output_dir",
    "descriptor",
    "evaluator_options",
    "lidar_extrinsic",
    "parse_methods",
    "read_parameter",
    "ros_advice",
    "summarizer_options",
]

_METHOD_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


# -- values → configurations (no ROS) --------------------------------------------------------


ROS_NAMES = FieldNames(
    {
        "methods": "methods",
        "right_views": "right_views",
        "confidences": "confidences",
        "confidence_presets": "confidence_presets",
        "gt_topic": "gt_topic",
        "gt_kind": "gt_kind",
        "left_info_topic": "left_camera_info",
        "right_info_topic": "right_camera_info",
        "left_image_topic": "left_image_topic",
        "right_image_topic": "right_image_topic",
        "temporal": "temporal",
        "pair_gap_ns": "pair_gap",
        "egomotion": "egomotion",
        "flicker": "flicker",
    },
    one="parameter ",
    many="parameters ",
    advice={"left_info_topic": "then the camera comes from each DisparityImage's f and t"},
)
"""How the parameters name :class:`CoreConfig`'s fields in its errors."""


def _named(items: Sequence[str], parameter: str, shape: str, example: str) -> list[tuple[str, str]]:
    """``NAME:VALUE`` strings → (name, value) pairs split at the first colon (one line if not)."""
    pairs = []
    for item in items:
        name, sep, value = (part.strip() for part in item.partition(":"))
        if not sep or not name or not value:
            raise ConfigurationError(
                f"parameter {parameter}: '{item}' is not {shape} (e.g. {example})"
            )
        pairs.append((name, value))
    return pairs


def parse_methods(items: Sequence[str], parameter: str = "methods") -> dict[str, str]:
    """``NAME:TOPIC`` strings → {name: topic}; names must be usable in topic names."""
    pairs = _named(items, parameter, "NAME:TOPIC", "sgbm:/stereo/sgbm/disparity")
    for name, _ in pairs:
        if not _METHOD_NAME.fullmatch(name) or "__" in name:
            raise ConfigurationError(
                f"parameter {parameter}: method name '{name}' must be letters, digits and _ "
                f"(no leading digit, no __): it becomes part of {NAMESPACE}/NAME/... topics"
            )
    methods = ROS_NAMES.unique(pairs, parameter)
    if not methods:
        raise ConfigurationError(
            "parameter methods is empty: give at least one NAME:TOPIC "
            "(e.g. methods:=\"['sgbm:/stereo/sgbm/disparity']\")"
        )
    return methods


def _named_presets(items: Sequence[str]) -> dict[str, str]:
    """``confidence_presets``: ``NAME:PRESET`` strings → {name: preset} (``higher:0:1`` too)."""
    pairs = _named(items, "confidence_presets", "NAME:PRESET", "zed_depth:zed")
    return ROS_NAMES.unique(pairs, "confidence_presets")


def lidar_extrinsic(text: str, parameter: str = "lidar_extrinsic") -> tuple[float, ...] | None:
    """The ``lidar_extrinsic`` parameter: None (use /tf_static) or the 4×4 matrix's 16 numbers.

    ``camera_mount`` is read the same way (``parameter`` names it in the errors).
    """
    from dispeval_ros.core.transforms import rigid_matrix
    from dispeval_ros.io.lidar import read_extrinsic

    text = text.strip()
    if not text:
        return None
    try:
        values = [float(token) for token in re.split(r"[\s,;\[\]]+", text) if token]
    except ValueError:
        matrix = read_extrinsic(Path(text).expanduser())  # not numbers: a file
    else:
        try:
            matrix = rigid_matrix(values, f"parameter {parameter}")
        except DispevalError as error:
            raise ConfigurationError(str(error)) from None
    return tuple(float(v) for v in matrix.reshape(-1))


def core_config(values: Mapping[str, Any]) -> CoreConfig:
    """The evaluation core's configuration from the evaluator's parameter values."""
    config = _core_config(values)
    refuse_live_confidences(config, ROS_NAMES)
    return config


def _core_config(values: Mapping[str, Any]) -> CoreConfig:
    """:func:`core_config` before the live front end's own checks."""
    gt_topic = str(values["gt_topic"]).strip()
    kind = str(values["gt_kind"])
    left_image = str(values.get("left_image_topic", "")).strip()
    right_image = str(values.get("right_image_topic", "")).strip()
    if kind == "none":  # the core's GT topic is then the left image (its frame clock)
        if gt_topic:
            raise ConfigurationError(
                "parameter gt_kind is none but gt_topic is set: leave gt_topic empty"
            )
        gt_topic = left_image
    right_views = tuple(values.get("right_views", ()))
    confidences = tuple(values.get("confidences", ()))
    presets = tuple(values.get("confidence_presets", ()))
    gt_free_criteria = tuple(values.get("gt_free_criteria", core_default("gt_free_criteria")))
    scale = float(values["gt_scale"])
    if not (math.isfinite(scale) and scale >= 0):
        raise ConfigurationError(f"parameter gt_scale must be >= 0 (0 = default), got {scale}")
    criteria = tuple(values["criteria"])
    if not criteria:
        raise ConfigurationError("parameter criteria is empty: name at least one criterion")
    measures = tuple(values["measures"])
    if measures == (DEFAULT_MEASURES_KEYWORD,):
        measures = ()  # the core's default for the ground-truth kind
    left = str(values["left_camera_info"]).strip()
    right = str(values["right_camera_info"]).strip()
    return CoreConfig(
        methods=parse_methods(values["methods"]),
        gt_topic=gt_topic,
        gt_kind=kind,
        extrinsic=lidar_extrinsic(str(values.get("lidar_extrinsic", ""))),
        cloud_filter=str(values.get("cloud_filter", core_default("cloud_filter"))),
        gt_scale=scale if scale > 0 else None,
        left_info_topic=left or None,
        right_info_topic=right or None,
        criteria=criteria,
        measures=measures or None,
        missing=str(values["missing"]),
        delta=float(values["delta"]),
        mu=float(values["mu"]),
        tolerance_ns=_seconds_to_ns(values["sync_tolerance"], "sync_tolerance"),
        lateness_ns=_seconds_to_ns(values["lateness"], "lateness"),
        left_image_topic=left_image or None,
        right_image_topic=right_image or None,
        right_views=parse_methods(right_views, "right_views") if right_views else {},
        confidences=parse_methods(confidences, "confidences") if confidences else {},
        confidence_presets=_named_presets(presets),
        gt_free_criteria=gt_free_criteria,
        temporal=str(values.get("temporal", "")).strip() or None,
        pair_gap_ns=_seconds_to_ns(
            values.get("pair_gap", core_default("pair_gap_ns") / 1e9), "pair_gap"
        ),
        egomotion=bool(values.get("egomotion", core_default("egomotion"))),
        flicker=int(values.get("flicker", core_default("flicker"))),
        names=ROS_NAMES,
    )


@dataclass(frozen=True)
class EvaluatorOptions:
    """Everything the evaluator node needs besides the core configuration."""

    core: CoreConfig
    alarms: AlarmThresholds
    queue_size: int
    max_buffered: int
    error_images: bool
    bag: Path | None
    bag_rate: float | None
    """None: as fast as scoring allows."""
    bag_loop: bool
    bag_wait_subscribers: int
    bag_exit: bool
    odometry_topic: str | None = None
    """With ``egomotion``: the nav_msgs/Odometry topic of the camera's motion (None: /tf)."""
    camera_mount: tuple[float, ...] | None = None
    """With ``odometry_topic``: the odometry's child frame → left optical frame (16 numbers)."""


def evaluator_options(values: Mapping[str, Any]) -> EvaluatorOptions:
    """The evaluator node's options from its parameter values (all checked here)."""
    bag = str(values["bag"]).strip()
    rate = float(values["bag_rate"])
    if not (math.isfinite(rate) and rate >= 0):
        raise ConfigurationError(f"parameter bag_rate must be >= 0, got {rate}")
    return EvaluatorOptions(
        core=core_config(values),
        alarms=AlarmThresholds.parse(values["alarm_warn"], values["alarm_error"]),
        queue_size=_positive_int(values["queue_size"], "queue_size"),
        max_buffered=_positive_int(values["max_buffered"], "max_buffered"),
        error_images=bool(values["error_images"]),
        bag=Path(bag).expanduser() if bag else None,
        bag_rate=rate if rate > 0 else None,
        bag_loop=bool(values["bag_loop"]),
        bag_wait_subscribers=max(0, int(values["bag_wait_subscribers"])),
        bag_exit=bool(values["bag_exit"]),
        **odometry_options(values),
    )


def odometry_options(values: Mapping[str, Any]) -> dict[str, Any]:
    """``odometry_topic`` and ``camera_mount``: each needs the one before it (one line if not)."""
    odometry = str(values.get("odometry_topic", "")).strip()
    mount = lidar_extrinsic(str(values.get("camera_mount", "")), "camera_mount")
    if odometry and not values.get("egomotion"):
        raise ConfigurationError(
            "parameter odometry_topic moves the camera for egomotion: set egomotion:=true too"
        )
    if mount is not None and not odometry:
        raise ConfigurationError(
            "parameter camera_mount mounts the camera on the odometry's child frame: give "
            "odometry_topic too (with /tf, the mount comes from /tf_static)"
        )
    return {"odometry_topic": odometry or None, "camera_mount": mount}


@dataclass(frozen=True)
class SummarizerOptions:
    """The summarizer core's configuration and the node's shutdown drain."""

    config: SummarizerConfig
    drain_timeout: float


def default_output_dir(now: float | None = None) -> Path:
    """``$ROS_HOME/dispeval/YYYYmmdd-HHMMSS`` (``ROS_HOME`` defaults to ``~/.ros``)."""
    home = os.environ.get("ROS_HOME") or str(Path.home() / ".ros")
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(now))
    return Path(home).expanduser() / "dispeval" / stamp


def summarizer_options(values: Mapping[str, Any]) -> SummarizerOptions:
    """The summarizer node's options from its parameter values (all checked here)."""
    granularity = str(values["objectives"])
    if granularity not in GRANULARITIES:
        raise ConfigurationError(
            f"parameter objectives must be one of {', '.join(GRANULARITIES)}, got '{granularity}'"
        )
    measures = tuple(values["objective_measures"])
    out = str(values["output_dir"]).strip()
    drain = float(values["drain_timeout"])
    if not (math.isfinite(drain) and drain >= 0):
        raise ConfigurationError(f"parameter drain_timeout must be >= 0, got {drain}")
    return SummarizerOptions(
        config=SummarizerConfig(
            out=Path(out).expanduser() if out else default_output_dir(),
            objective_measures=measures,
            granularity=granularity,
            every_n=_positive_int(values["summary_every"], "summary_every"),
            resume=bool(values["resume"]),
        ),
        drain_timeout=drain,
    )


def ros_advice(conflict: ResultsConflictError) -> ConfigurationError:
    """A results-folder conflict with its remedy in ROS parameter terms (never CLI options)."""
    return conflict.advised(
        resume="set resume:=true to continue them",
        same_options="resume with the same parameters",
        elsewhere="set another output_dir",
    )


def _seconds_to_ns(value: Any, name: str) -> int:
    seconds = float(value)
    if not (math.isfinite(seconds) and seconds >= 0):
        raise ConfigurationError(f"parameter {name} must be a number of seconds >= 0, got {value}")
    return round(seconds * NS_PER_SECOND)


def _positive_int(value: Any, name: str) -> int:
    number = int(value)
    if number < 1:
        raise ConfigurationError(f"parameter {name} must be at least 1, got {number}")
    return number


# -- declaring and reading (rclpy) ------------------------------------------------------------


def descriptor(param: Param) -> Any:
    """The ``rcl_interfaces/msg/ParameterDescriptor`` of one table row."""
    from rcl_interfaces.msg import (
        FloatingPointRange,
        IntegerRange,
        ParameterDescriptor,
        ParameterType,
    )

    types = {
        BOOL: ParameterType.PARAMETER_BOOL,
        INTEGER: ParameterType.PARAMETER_INTEGER,
        DOUBLE: ParameterType.PARAMETER_DOUBLE,
        STRING: ParameterType.PARAMETER_STRING,
        STRING_ARRAY: ParameterType.PARAMETER_STRING_ARRAY,
    }
    result = ParameterDescriptor(
        name=param.name,
        type=types[param.kind],
        description=param.description,
        additional_constraints=param.constraints,
        read_only=param.read_only,
    )
    if param.low is not None and param.high is not None:
        if param.kind == DOUBLE:
            result.floating_point_range = [
                FloatingPointRange(
                    from_value=float(param.low), to_value=float(param.high), step=0.0
                )
            ]
        elif param.kind == INTEGER:
            result.integer_range = [
                IntegerRange(from_value=int(param.low), to_value=int(param.high), step=param.step)
            ]
    return result


def declare_parameters(node: Any, params: Sequence[Param]) -> dict[str, Any]:
    """Declare every row on ``node`` (overrides from YAML / ``-p`` apply) and read the values.

    Empty string arrays are declared by type (``Parameter.Type.STRING_ARRAY``; rclpy would
    type an empty list default as a byte array), then given a typed empty value when no file
    or ``-p`` set them: a parameter left unset makes rclpy's GetParameters service answer
    nothing for the whole node (``ros2 param dump`` prints ``{}``).
    """
    from rclpy.parameter import Parameter

    for param in params:
        if param.default is None or param.default == ():
            node.declare_parameter(param.name, Parameter.Type.STRING_ARRAY, descriptor(param))
            not_set = Parameter(param.name, Parameter.Type.NOT_SET)
            unset = node.get_parameter_or(param.name, not_set).type_ == Parameter.Type.NOT_SET
            if param.default == () and unset:
                node.set_parameters([Parameter(param.name, Parameter.Type.STRING_ARRAY, [])])
        else:
            default = list(param.default) if isinstance(param.default, tuple) else param.default
            node.declare_parameter(param.name, default, descriptor(param))
    return {param.name: read_parameter(node, param) for param in params}


def read_parameter(node: Any, param: Param) -> ParamValue:
    """The value of a declared parameter; its default while unset (e.g. ``[]`` in YAML)."""
    from rclpy.parameter import Parameter

    value = node.get_parameter_or(param.name, Parameter(param.name, Parameter.Type.NOT_SET)).value
    if value is None:
        return param.empty_default
    if param.kind == STRING_ARRAY:
        return tuple(str(item) for item in value)
    return value
