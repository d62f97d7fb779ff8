"""What both nodes share: their parameter tables and the process life cycle.

Each parameter is declared from one row of a table (name, default, description, constraints,
numeric range, read-only), so descriptions, ``ros2 param describe`` and the config YAML files
agree. The values read back are turned into :class:`~dispeval_ros.stream.core.CoreConfig` /
:class:`~dispeval_ros.stream.summarizer.SummarizerConfig` here; every user mistake is a
:class:`~dispeval_ros.errors.ConfigurationError` naming the parameter.

rclpy is imported inside the functions that need it only, so the tables and conversions import
(and can be checked) without ROS.
"""

from __future__ import annotations

import math
import os
import re
import signal
import threading
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dispeval_ros.core import registry
from dispeval_ros.core.objectives import DEFAULT_OBJECTIVES_TEXT
from dispeval_ros.errors import ConfigurationError, DispevalError, ResultsConflictError
from dispeval_ros.stream.core import GT_KINDS, CoreConfig
from dispeval_ros.stream.join import LATENESS_RULE
from dispeval_ros.stream.summarizer import SummarizerConfig
from dispeval_ros.stream.vectors import AlarmThresholds
from dispeval_ros.summary import GRANULARITIES

BOOL, INTEGER, DOUBLE, STRING, STRING_ARRAY = "bool", "integer", "double", "string", "string[]"
DEFAULT_MEASURES_KEYWORD = "default"
"""``measures: [default]``: the core's default measures for the kind of ground truth."""

ParamValue = bool | int | float | str | tuple[str, ...]

_METHOD_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NS = 1_000_000_000


@dataclass(frozen=True)
class Param:
    """One ROS parameter: its type, default and the text ``ros2 param describe`` shows.

    Every parameter has a value once declared (``ros2 param get``/``dump`` answer only for a
    node whose parameters all have one). ``default`` None marks a required string array with no
    default (``methods``: the node refuses to start without it); ``()`` is an empty string
    array, which ROS cannot type from ``[]``: it is declared by type, then set to a typed
    empty array unless a parameter file gave it.
    """

    name: str
    kind: str
    default: ParamValue | None
    description: str
    constraints: str = ""
    read_only: bool = True
    low: float | None = None
    high: float | None = None

    @property
    def empty_default(self) -> ParamValue:
        """The value used while the parameter is unset."""
        return () if self.default is None else self.default


EVALUATOR_PARAMETERS: tuple[Param, ...] = (
    Param(
        "methods",
        STRING_ARRAY,
        None,
        "Methods to evaluate, each NAME:TOPIC of a stereo_msgs/msg/DisparityImage topic. "
        "NAME appears in the output topics /dispeval/NAME/...",
        "at least one; NAME: letters, digits and _ (no leading digit, no __); topics distinct",
    ),
    Param(
        "gt_topic",
        STRING,
        "",
        "Ground-truth sensor_msgs/msg/Image topic (disparity in px or depth, see gt_kind)",
        "required unless gt_kind is none; encodings 32FC1, 64FC1, 16UC1, mono16",
    ),
    Param(
        "gt_kind",
        STRING,
        "disparity",
        "What the ground truth is: a disparity or depth Image, or a LiDAR's "
        "sensor_msgs/msg/PointCloud2 projected into the left camera (pointcloud: needs both "
        "CameraInfo topics; see lidar_extrinsic and cloud_filter); none: no ground truth, only "
        "the ground-truth-free measures of left_image_topic and right_image_topic",
        "disparity | depth | pointcloud | none",
    ),
    Param(
        "left_image_topic",
        STRING,
        "",
        "Left rectified sensor_msgs/msg/Image: with right_image_topic, the ground-truth-free "
        "measures vpe (view-prediction error, grey levels) and lrc on gtfree:* criteria. Empty: "
        "none",
        "give both image topics or neither; encodings mono8, 8UC1, rgb8, bgr8 (both grey or "
        "both colour)",
    ),
    Param(
        "right_image_topic",
        STRING,
        "",
        "Right rectified sensor_msgs/msg/Image (warped into the left view by each estimate)",
        "give both image topics or neither",
    ),
    Param(
        "right_views",
        STRING_ARRAY,
        (),
        "Right-view stereo_msgs/msg/DisparityImage of some methods, each NAME:TOPIC, for their "
        "left-right inconsistency lrc (needs the image topics). Read at start only (an empty "
        "array default cannot be read-only in ROS)",
        "NAME of a method in methods; topics distinct from every other topic",
        read_only=False,
    ),
    Param(
        "gt_free_criteria",
        STRING_ARRAY,
        ("all", "texture"),
        "Criterion sets of the ground-truth-free measures: all, texture (textured / textureless "
        "from the left image, Middlebury 2001 rule)",
        "all, texture",
    ),
    Param(
        "lidar_extrinsic",
        STRING,
        "",
        "gt_kind pointcloud: the cloud frame -> left camera optical frame transform, as 16 "
        "numbers (4x4 row-major), 7 ('x y z qx qy qz qw') or a file holding either. Empty: "
        "the chain from /tf_static (through tf2_ros where it is installed)",
        "empty, 16 or 7 numbers, or a file",
    ),
    Param(
        "cloud_filter",
        STRING,
        "7,0.1",
        "gt_kind pointcloud: LiDAR-camera parallax filter 'W,G': a point is dropped when a point "
        "within its WxW pixel window is nearer by more than the relative gap G; '0' disables",
        "'W,G' (W integer px, G >= 0) or '0'",
    ),
    Param(
        "gt_scale",
        DOUBLE,
        0.0,
        "Ground-truth values are divided by this. 0 = default: 16-bit disparity / 256 (KITTI), "
        "16-bit depth / 1000 (mm to m), float images as they are",
        ">= 0",
        low=0.0,
        high=1e9,
    ),
    Param(
        "left_camera_info",
        STRING,
        "",
        "Left rectified sensor_msgs/msg/CameraInfo topic (f = P[0]). Empty: the camera comes from "
        "the f and t fields of each DisparityImage",
        "give both CameraInfo topics or neither",
    ),
    Param(
        "right_camera_info",
        STRING,
        "",
        "Right rectified sensor_msgs/msg/CameraInfo topic (baseline = -P[3] / P[0])",
        "give both CameraInfo topics or neither",
    ),
    Param(
        "criteria",
        STRING_ARRAY,
        ("all", "visibility", "depth"),
        "Evaluation criteria: set partitions of the valid ground-truth points",
        "all, visibility, depth, legacy (roi needs a mask and is not available live)",
    ),
    Param(
        "measures",
        STRING_ARRAY,
        (DEFAULT_MEASURES_KEYWORD,),
        "Error measures. 'default' = the summable default set (every default measure except the "
        "quantiles aNN, which cannot be added over frames), plus the depth-domain measures for "
        "pointcloud ground truth",
        f"default, or a list of: {registry.listing(', ')}",
    ),
    Param(
        "missing",
        STRING,
        "interpolate",
        "How missing estimates (outside the DisparityImage's [min, max] disparity) are scored",
        "interpolate | thesis | ignore",
    ),
    Param(
        "delta",
        DOUBLE,
        1.0,
        "Error threshold delta (px) of BMP and BMPRE",
        "> 0",
        low=0.0,
        high=1e6,
    ),
    Param(
        "mu",
        DOUBLE,
        0.01,
        "mu (px) of SZE: keeps f*B/(d + mu) finite where d = 0",
        "> 0",
        low=0.0,
        high=1e6,
    ),
    Param(
        "sync_tolerance",
        DOUBLE,
        0.01,
        "Largest |estimate stamp - ground-truth stamp| (s) for pairing frames whose header stamps "
        "differ (equal stamps always pair)",
        "[0, 60] s",
        low=0.0,
        high=60.0,
    ),
    Param(
        "lateness",
        DOUBLE,
        1.0,
        f"{LATENESS_RULE[0].upper()}{LATENESS_RULE[1:]} (s)",
        "[0, 600] s",
        low=0.0,
        high=600.0,
    ),
    Param(
        "queue_size",
        INTEGER,
        4,
        "Joined frames waiting to be scored; when scoring falls behind the oldest waiting frame "
        "is dropped (and counted)",
        "[1, 100000]",
        low=1,
        high=100_000,
    ),
    Param(
        "max_buffered",
        INTEGER,
        256,
        "Messages held while waiting for the other topics of a frame; beyond it the oldest "
        "ground-truth frame is dropped (bounded memory)",
        "[1, 10000000]",
        low=1,
        high=10_000_000,
    ),
    Param(
        "error_images",
        BOOL,
        False,
        "Also publish /dispeval/NAME/error (32FC1 absolute error, NaN where not evaluated) and "
        "/dispeval/NAME/error_color (rgb8, criteria borders in white)",
    ),
    Param(
        "alarm_warn",
        STRING_ARRAY,
        (),
        "WARN level in /dispeval/scores when CRITERION/MEASURE exceeds VALUE (density: falls "
        "below it). Can be changed at run time",
        "each CRITERION/MEASURE=VALUE, e.g. all/bmp=20",
        read_only=False,
    ),
    Param(
        "alarm_error",
        STRING_ARRAY,
        (),
        "ERROR level in /dispeval/scores when CRITERION/MEASURE exceeds VALUE (density: falls "
        "below it). Can be changed at run time",
        "each CRITERION/MEASURE=VALUE, e.g. all/bmp=40",
        read_only=False,
    ),
    Param(
        "bag",
        STRING,
        "",
        "Replay this recording (rosbag2 folder, .mcap, .db3 or ROS 1 .bag) through the evaluator "
        "instead of subscribing. Empty: subscribe to the live topics",
    ),
    Param(
        "bag_rate",
        DOUBLE,
        1.0,
        "Replay speed: 1 = recorded timing, 2 = twice as fast, 0 = as fast as scoring allows "
        "(then no frame is ever dropped)",
        "[0, 1000]",
        low=0.0,
        high=1000.0,
    ),
    Param(
        "bag_loop",
        BOOL,
        False,
        "Replay the bag again and again; each pass is shifted in time so it continues the last",
    ),
    Param(
        "bag_wait_subscribers",
        INTEGER,
        0,
        "Before replaying, wait until /dispeval/scores has this many matched subscribers (e.g. 1 "
        "so that the summarizer sees every frame)",
        "[0, 1000]",
        low=0,
        high=1000,
    ),
    Param(
        "bag_exit",
        BOOL,
        True,
        "When a replay (without bag_loop) has ended: score what remains, publish it and exit",
    ),
)

SUMMARIZER_PARAMETERS: tuple[Param, ...] = (
    Param(
        "output_dir",
        STRING,
        "",
        "Results folder: results.sqlite (as frames come), frames.csv and summary.json (at "
        "shutdown). Empty: $ROS_HOME/dispeval/YYYYmmdd-HHMMSS (ROS_HOME defaults to ~/.ros)",
        "must not hold results already unless resume is true",
    ),
    Param(
        "objective_measures",
        STRING_ARRAY,
        (),
        "Measures compared by the Pareto models (A*, A* Groups, front reduction). Empty: "
        + DEFAULT_OBJECTIVES_TEXT
        + ". Read at start only (an empty array default cannot be read-only in ROS)",
        "measures the evaluator computes",
        read_only=False,
    ),
    Param(
        "objectives",
        STRING,
        "sequence",
        "One objective per (criterion, sequence), or per (criterion, frame)",
        "sequence | frame",
    ),
    Param(
        "summary_every",
        INTEGER,
        10,
        "Store the frames and recompute the groups every this many frames (a crash loses at most "
        "this many)",
        "[1, 1000000]",
        low=1,
        high=1_000_000,
    ),
    Param(
        "resume",
        BOOL,
        False,
        "Continue the results already in output_dir; new frames start a new sequence",
    ),
    Param(
        "drain_timeout",
        DOUBLE,
        3.0,
        "At shutdown, keep receiving scores for up to this many seconds while an evaluator is "
        "still publishing its last frames",
        "[0, 600] s",
        low=0.0,
        high=600.0,
    ),
)


# -- values → configurations (no ROS) --------------------------------------------------------


def parse_methods(items: Sequence[str], parameter: str = "methods") -> dict[str, str]:
    """``NAME:TOPIC`` strings → {name: topic}; names must be usable in topic names."""
    methods: dict[str, str] = {}
    for item in items:
        name, sep, topic = (part.strip() for part in item.partition(":"))
        if not sep or not name or not topic:
            raise ConfigurationError(
                f"parameter {parameter}: '{item}' is not NAME:TOPIC (e.g. sgbm:/stereo/sgbm/disparity)"
            )
        if not _METHOD_NAME.fullmatch(name) or "__" in name:
            raise ConfigurationError(
                f"parameter {parameter}: method name '{name}' must be letters, digits and _ "
                "(no leading digit, no __): it becomes part of /dispeval/NAME/... topics"
            )
        if name in methods:
            raise ConfigurationError(f"parameter {parameter}: method '{name}' is given twice")
        methods[name] = topic
    if not methods:
        raise ConfigurationError(
            "parameter methods is empty: give at least one NAME:TOPIC "
            "(e.g. methods:=\"['sgbm:/stereo/sgbm/disparity']\")"
        )
    return methods


def lidar_extrinsic(text: str) -> tuple[float, ...] | None:
    """The ``lidar_extrinsic`` parameter: None (use /tf_static) or the 4×4 matrix's 16 numbers."""
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
            matrix = rigid_matrix(values, "parameter lidar_extrinsic")
        except DispevalError as error:
            raise ConfigurationError(str(error)) from None
    return tuple(float(v) for v in matrix.reshape(-1))


def core_config(values: Mapping[str, Any]) -> CoreConfig:
    """The evaluation core's configuration from the evaluator's parameter values."""
    gt_topic = str(values["gt_topic"]).strip()
    kind = str(values["gt_kind"])
    if kind not in GT_KINDS:
        raise ConfigurationError(
            f"parameter gt_kind must be one of {', '.join(GT_KINDS)}, got '{kind}'"
        )
    left_image = str(values.get("left_image_topic", "")).strip()
    right_image = str(values.get("right_image_topic", "")).strip()
    if bool(left_image) != bool(right_image):
        raise ConfigurationError(
            "parameters left_image_topic and right_image_topic: give both image topics or neither"
        )
    if kind == "none":
        if not left_image:
            raise ConfigurationError(
                "parameter gt_kind is none: give left_image_topic and right_image_topic (the "
                "ground-truth-free measures need them)"
            )
        if gt_topic:
            raise ConfigurationError(
                "parameter gt_kind is none but gt_topic is set: leave gt_topic empty"
            )
        gt_topic = left_image
    elif not gt_topic:
        raise ConfigurationError("parameter gt_topic is empty: name the ground-truth Image topic")
    right_views = tuple(values.get("right_views", ()))
    gt_free_criteria = tuple(values.get("gt_free_criteria", ("all", "texture")))
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
    if bool(left) != bool(right):
        raise ConfigurationError(
            "parameters left_camera_info and right_camera_info: give both CameraInfo topics or "
            "neither (then the camera comes from each DisparityImage's f and t)"
        )
    return CoreConfig(
        methods=parse_methods(values["methods"]),
        gt_topic=gt_topic,
        gt_kind=kind,
        extrinsic=lidar_extrinsic(str(values.get("lidar_extrinsic", ""))),
        cloud_filter=str(values.get("cloud_filter", "7,0.1")),
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
        gt_free_criteria=gt_free_criteria,
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
    )


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
    return round(seconds * _NS)


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
                IntegerRange(from_value=int(param.low), to_value=int(param.high), step=1)
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


# -- process life cycle ------------------------------------------------------------------------

SPIN_PERIOD = 0.1
"""Seconds between checks for a stop request while spinning."""
DUPLICATE_SIGNAL_WINDOW = 1.0
"""A second SIGINT sooner than this after the first is a copy, not a request to abort."""


def install_stop_handlers(stop: threading.Event) -> Callable[[], None]:
    """SIGINT / SIGTERM set ``stop`` (orderly shutdown); a later second SIGINT aborts it.

    rclpy's own handlers are not installed (``SignalHandlerOptions.NO``): they would shut the
    context down at once, so the last frames could no longer be published. Returns a function
    that restores the previous handlers. Does nothing outside the main thread.
    """
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    first: list[float] = []

    def on_sigint(signum: int, frame: object) -> None:
        # A copy of the first SIGINT (the terminal's and launch's, nearly at once) is ignored.
        if first and time.monotonic() - first[0] > DUPLICATE_SIGNAL_WINDOW:
            raise KeyboardInterrupt
        if not first:
            first.append(time.monotonic())
        stop.set()

    def on_sigterm(signum: int, frame: object) -> None:
        stop.set()

    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, on_sigint)
    signal.signal(signal.SIGTERM, on_sigterm)

    def restore() -> None:
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)

    return restore


def run_node(
    factory: Callable[[threading.Event], Any], name: str, args: Sequence[str] | None
) -> int:
    """Init rclpy, create the node, spin until a stop request, finish, tear down; exit code.

    ``factory(stop)`` builds the node; the node may set ``stop`` itself (e.g. at the end of a
    bag). After spinning, ``node.finish(executor)`` runs while the context is still valid, so
    the last results are published and every file is written; then the node is destroyed and
    rclpy shut down. A user mistake in the parameters exits with 2, after one log line.
    """
    import rclpy
    import rclpy.logging
    from rclpy.exceptions import NameValidationException, ParameterException
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(
        args=list(args) if args is not None else None,
        signal_handler_options=SignalHandlerOptions.NO,
    )
    stop = threading.Event()
    restore = install_stop_handlers(stop)
    logger = rclpy.logging.get_logger(name)
    node: Any = None
    executor: Any = None
    code = 0
    try:
        try:
            node = factory(stop)
        except (DispevalError, ParameterException, NameValidationException) as error:
            logger.fatal(str(error))
            return 2
        logger = node.get_logger()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        try:
            while not stop.is_set() and rclpy.ok():
                executor.spin_once(timeout_sec=SPIN_PERIOD)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        except Exception:  # a bug in a callback: still finish what was received
            logger.error("stopping after an unexpected error:\n" + traceback.format_exc())
            code = 1
        stop.set()
        logger.info("stopping: finishing the frames received so far")
        try:
            node.finish(executor)
        except KeyboardInterrupt:
            logger.warning("second interrupt: stopped without finishing")
            code = max(code, 130)
        code = max(code, int(getattr(node, "exit_code", 0)))
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        restore()
        rclpy.try_shutdown()
    return code
