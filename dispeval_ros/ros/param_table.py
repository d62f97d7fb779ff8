"""The parameter tables of both nodes: names, types, defaults, descriptions, ranges.

Each parameter is declared from one row (see :func:`dispeval_ros.ros.params.declare_parameters`),
so descriptions, ``ros2 param describe`` and the config YAML files agree. The defaults of the
evaluation options are :class:`~dispeval_ros.stream.config.CoreConfig`'s own (the YAML files are
pinned to this table by a test). Imports without ROS.
"""

from __future__ import annotations

from dataclasses import dataclass

from dispeval_ros.core import registry
from dispeval_ros.core.objectives import DEFAULT_OBJECTIVES_TEXT
from dispeval_ros.core.temporal import PRESETS
from dispeval_ros.stream.alarms import DELAY_ALARM
from dispeval_ros.stream.config import QUEUE_SIZE, core_default, field_default
from dispeval_ros.stream.flicker import FLICKER_RULE
from dispeval_ros.stream.join import LATENESS_RULE
from dispeval_ros.stream.pairs import DRIFT_RULE, PAIR_GAP_RULE
from dispeval_ros.stream.summarizer import SummarizerConfig
from dispeval_ros.stream.topics import (
    ERROR_COLOR_LEAF,
    ERROR_LEAF,
    NAMESPACE,
    SCORES_TOPIC,
    method_topic,
)

BOOL, INTEGER, DOUBLE, STRING, STRING_ARRAY = "bool", "integer", "double", "string", "string[]"
DEFAULT_MEASURES_KEYWORD = "default"
"""``measures: [default]``: the core's default measures for the kind of ground truth."""

ParamValue = bool | int | float | str | tuple[str, ...]
NS_PER_SECOND = 1_000_000_000


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
    step: int = 1
    """An integer range's step (the values are ``low + k·step``, and ``high``)."""

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
        f"NAME appears in the output topics {NAMESPACE}/NAME/...",
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
        core_default("gt_kind"),
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
        "confidences",
        STRING_ARRAY,
        (),
        "Confidence maps (sensor_msgs/msg/Image) of some methods, each NAME:TOPIC, joined by "
        "stamp with their estimates: sparsification curves, AUC and AUSE by criterion (needs a "
        "ground truth). Refused by the live node for now (its sums are not published yet: "
        "record the topics and run dispeval bag). Read at start only",
        "NAME of a method in methods; topics distinct from every other topic",
        read_only=False,
    ),
    Param(
        "confidence_presets",
        STRING_ARRAY,
        (),
        "Each confidence's convention, NAME:PRESET (zed, realsense, vpi, wls, higher, lower, "
        "higher:LOW:HIGH, lower:LOW:HIGH); a method not named takes higher. Read at start only",
        "NAME of a method in confidences",
        read_only=False,
    ),
    Param(
        "gt_free_criteria",
        STRING_ARRAY,
        tuple(core_default("gt_free_criteria")),
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
        core_default("cloud_filter"),
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
        tuple(core_default("criteria")),
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
        core_default("missing"),
        "How missing estimates (outside the DisparityImage's [min, max] disparity) are scored",
        "interpolate | thesis | ignore",
    ),
    Param(
        "delta",
        DOUBLE,
        float(core_default("delta")),
        "Error threshold delta (px) of BMP and BMPRE",
        "> 0",
        low=0.0,
        high=1e6,
    ),
    Param(
        "mu",
        DOUBLE,
        float(core_default("mu")),
        "mu (px) of SZE: keeps f*B/(d + mu) finite where d = 0",
        "> 0",
        low=0.0,
        high=1e6,
    ),
    Param(
        "sync_tolerance",
        DOUBLE,
        core_default("tolerance_ns") / NS_PER_SECOND,
        "Largest |estimate stamp - ground-truth stamp| (s) for pairing frames whose header stamps "
        "differ (equal stamps always pair)",
        "[0, 60] s",
        low=0.0,
        high=60.0,
    ),
    Param(
        "lateness",
        DOUBLE,
        core_default("lateness_ns") / NS_PER_SECOND,
        f"{LATENESS_RULE[0].upper()}{LATENESS_RULE[1:]} (s)",
        "[0, 600] s",
        low=0.0,
        high=600.0,
    ),
    Param(
        "temporal",
        STRING,
        "",
        "Also score each method's frame-to-frame consistency (tepe, tepe_r, tepe_bad_X) over "
        "consecutive ground-truth frames, normalised as this preset (docs/method.md); empty: off",
        f"empty | {' | '.join(PRESETS)}",
    ),
    Param(
        "pair_gap",
        DOUBLE,
        core_default("pair_gap_ns") / NS_PER_SECOND,
        f"With temporal, egomotion or flicker: {PAIR_GAP_RULE} (s)",
        "(0, 600] s",
        low=0.0,
        high=600.0,
    ),
    Param(
        "egomotion",
        BOOL,
        core_default("egomotion"),
        "Also score each method's ego-motion residual over the same pairs (ground-truth-free "
        "temporal noise on gtfree:* criteria, not bias): the estimate moved by the camera's "
        "motion, from /tf and /tf_static (tf2_msgs) or odometry_topic. Needs the CameraInfo "
        f"topics. {DRIFT_RULE[0].upper()}{DRIFT_RULE[1:]}",
    ),
    Param(
        "flicker",
        INTEGER,
        core_default("flicker"),
        f"Frames per window of the {FLICKER_RULE}; 0: off. Assumes a static camera (checked "
        "against /tf with egomotion)",
        "0 or [2, 1000]",
        low=0,
        high=1000,
    ),
    Param(
        "odometry_topic",
        STRING,
        "",
        "With egomotion: a nav_msgs/msg/Odometry topic whose pose (header.frame_id -> "
        "child_frame_id) moves the camera, read instead of /tf (robots that publish no /tf). "
        "Empty: /tf",
        "empty or a topic; needs egomotion",
    ),
    Param(
        "camera_mount",
        STRING,
        "",
        "With odometry_topic: the odometry's child frame -> left camera optical frame "
        "(the left CameraInfo's frame_id) transform, as 16 numbers (4x4 row-major), 7 "
        "('x y z qx qy qz qw') or a file holding either. Empty: the chain from /tf_static, "
        "or the odometry's child frame is the camera's",
        "empty, 16 or 7 numbers, or a file; needs odometry_topic",
    ),
    Param(
        "queue_size",
        INTEGER,
        QUEUE_SIZE,
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
        f"Also publish {method_topic('NAME', ERROR_LEAF)} (32FC1 absolute error, NaN where not "
        f"evaluated) and {method_topic('NAME', ERROR_COLOR_LEAF)} (rgb8, criteria borders in "
        "white)",
    ),
    Param(
        "alarm_warn",
        STRING_ARRAY,
        (),
        f"WARN level in {SCORES_TOPIC} when CRITERION/MEASURE exceeds VALUE (density: falls "
        f"below it; {DELAY_ALARM}: an estimate's delay in ms). Can be changed at run time",
        "each CRITERION/MEASURE=VALUE, e.g. all/bmp=20",
        read_only=False,
    ),
    Param(
        "alarm_error",
        STRING_ARRAY,
        (),
        f"ERROR level in {SCORES_TOPIC} when CRITERION/MEASURE exceeds VALUE (density: falls "
        f"below it; {DELAY_ALARM}: an estimate's delay in ms). Can be changed at run time",
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
        "Replay the bag again and again; each pass (its /tf too) is shifted in time so it "
        "continues the last",
    ),
    Param(
        "bag_wait_subscribers",
        INTEGER,
        0,
        f"Before replaying, wait until {SCORES_TOPIC} has this many matched subscribers (e.g. 1 "
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
        field_default(SummarizerConfig, "granularity"),
        "One objective per (criterion, sequence), or per (criterion, frame)",
        "sequence | frame",
    ),
    Param(
        "summary_every",
        INTEGER,
        field_default(SummarizerConfig, "every_n"),
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
