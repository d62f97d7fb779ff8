"""What an evaluation reads and how it scores it: :class:`CoreConfig`, its defaults and topics.

Every front end (``dispeval bag``/``live``, the ROS and DDS nodes, the report) builds this one
record: its field defaults are the defaults the options, the ROS parameter table and
``config/evaluator.yaml`` show (pinned by test/stream/test_config.py); its checks are the rules
every front end enforces, checked here only and worded with the front end's names of the fields
(:class:`FieldNames`, guarded by test/stream/test_config_rules.py); :attr:`CoreConfig.topics` is
the one list of the topics read (subscribed, replayed, checked and hashed for the provenance);
and :meth:`CoreConfig.from_record` reads back what :meth:`CoreConfig.as_record` stored with the
results.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import InitVar, dataclass, field
from typing import Any

from dispeval_ros.core.confidence import DEFAULT_PRESET, ConfidenceScorer, parse_preset
from dispeval_ros.core.criteria import LIDAR_DEPTH_RANGES
from dispeval_ros.core.egomotion import EgoMotionOptions
from dispeval_ros.core.evaluator import DEFAULT_CRITERIA, Evaluator
from dispeval_ros.core.gtfree import DEFAULT_GT_FREE_CRITERIA, GT_FREE_SCORED, GroundTruthFree
from dispeval_ros.core.lidar_drift import DriftOptions
from dispeval_ros.core.measures import DEPTH_MEASURES, SEQUENCE_MEASURES
from dispeval_ros.core.projection import CloudFilter
from dispeval_ros.core.temporal import PRESETS
from dispeval_ros.core.transforms import rigid_matrix
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.stream.flicker import FlickerStage
from dispeval_ros.stream.pairs import DEFAULT_PAIR_GAP_NS, PairStage

DISPARITY_TYPE = "stereo_msgs/msg/DisparityImage"
IMAGE_TYPE = "sensor_msgs/msg/Image"
CAMERA_INFO_TYPE = "sensor_msgs/msg/CameraInfo"
POINT_CLOUD_TYPE = "sensor_msgs/msg/PointCloud2"
TF_TYPE = "tf2_msgs/msg/TFMessage"
TF_STATIC_TOPIC = "/tf_static"
TF_TOPIC = "/tf"
"""The transforms over time (ego-motion: ``odom → base_link`` …), read with ``egomotion``."""
QUEUE_SIZE = 4
"""Joined frames waiting to be scored by a live front end before the oldest is dropped."""
GT_KINDS = ("disparity", "depth", "pointcloud", "none")
"""``none``: no ground truth; the left image is the frame clock and only the ground-truth-free
measures are scored."""
LEFT_IMAGE_KEY = "<left image>"
RIGHT_IMAGE_KEY = "<right image>"
RIGHT_VIEW_KEY = "<right view> "
CONFIDENCE_KEY = "<confidence> "
"""Join keys of the images, of each method's right-view disparity (``RIGHT_VIEW_KEY + name``)
and of its confidence map (``CONFIDENCE_KEY + name``): joined with the ground truth like a
method, never counted as one."""


@dataclass(frozen=True)
class FieldNames:
    """How a front end names :class:`CoreConfig`'s fields in the rules' messages.

    Each rule is checked once, in :class:`CoreConfig`; its message names the fields through this
    so that ``dispeval bag`` says ``--left-image`` and the ROS node ``parameter
    left_image_topic``. Fields not in ``names`` keep the neutral wording of :data:`NEUTRAL_NAMES`.
    """

    names: Mapping[str, str] = field(default_factory=dict)
    one: str = ""
    """Put before one field's name (``"parameter "``)."""
    many: str = ""
    """Put before two fields' names (``"parameters "``)."""
    advice: Mapping[str, str] = field(default_factory=dict)
    """Field → the front end's advice appended to the messages of the rules on it."""

    def of(self, *fields: str) -> str:
        """The fields as this front end names them: ``--left-image and --right-image``."""
        names = [self.names.get(name) or _NEUTRAL[name] for name in fields]
        return (self.one if len(names) == 1 else self.many) + " and ".join(names)

    def error(self, message: str, about: str) -> ConfigurationError:
        """The error of a rule on field ``about``, with the front end's advice on it."""
        advice = self.advice.get(about)
        return ConfigurationError(f"{message} ({advice})" if advice else message)

    def unique(self, pairs: Iterable[tuple[str, str]], about: str) -> dict[str, str]:
        """``(name, topic)`` pairs → {name: topic}; a name given twice is an error."""
        methods: dict[str, str] = {}
        for name, topic in pairs:
            if name in methods:
                raise self.error(f"{self.of(about)}: method '{name}' is given twice", about)
            methods[name] = topic
        return methods


_NEUTRAL = {
    "methods": "the methods",
    "right_views": "the right views",
    "confidences": "the confidence topics",
    "confidence_presets": "the confidence presets",
    "gt_topic": "the ground-truth topic",
    "gt_kind": "the ground-truth kind",
    "left_info_topic": "the left CameraInfo topic",
    "right_info_topic": "the right CameraInfo topic",
    "left_image_topic": "the left image topic",
    "right_image_topic": "the right image topic",
    "temporal": "the temporal preset",
    "pair_gap_ns": "the pair gap",
    "egomotion": "the ego-motion residual",
    "flicker": "the flicker window",
}
NEUTRAL_NAMES = FieldNames()
"""The wording for Python callers: fields named in plain words."""


@dataclass(frozen=True)
class CoreConfig:
    """What to evaluate: topics, ground-truth encoding, evaluation options, sync."""

    methods: Mapping[str, str]
    gt_topic: str
    gt_kind: str = "disparity"
    gt_scale: float | None = None
    left_info_topic: str | None = None
    right_info_topic: str | None = None
    criteria: Sequence[str] = DEFAULT_CRITERIA
    measures: Sequence[str] | None = None
    missing: str = "interpolate"
    delta: float = 1.0
    mu: float = 0.01
    tolerance_ns: int = 10_000_000
    lateness_ns: int = 1_000_000_000
    extrinsic: tuple[float, ...] | None = None
    """Point-cloud GT: the cloud → left camera transform (16 numbers, row-major); None reads
    the chain from /tf_static."""
    cloud_filter: str = str(CloudFilter())
    """Point-cloud GT: the parallax filter, ``"W,G"`` or ``"0"`` (see :class:`CloudFilter`)."""
    left_image_topic: str | None = None
    """Left rectified sensor_msgs/Image (mono8, 8UC1, rgb8 or bgr8): with the right one, the
    ground-truth-free measures (vpe, lrc) on ``gtfree:`` criteria."""
    right_image_topic: str | None = None
    right_views: Mapping[str, str] = field(default_factory=dict)
    """Method → its right-view DisparityImage topic (for lrc); optional per method."""
    gt_free_criteria: Sequence[str] = DEFAULT_GT_FREE_CRITERIA
    confidences: Mapping[str, str] = field(default_factory=dict)
    """Method → its confidence map's sensor_msgs/Image topic: sparsification curves, AUC and
    AUSE by criterion (:mod:`~dispeval_ros.core.confidence`); optional per method."""
    confidence_presets: Mapping[str, str] = field(default_factory=dict)
    """Method → its confidence's convention (a preset, ``higher:LOW:HIGH``…); a method of
    :attr:`confidences` not named here takes :data:`~dispeval_ros.core.confidence.DEFAULT_PRESET`."""
    temporal: str | None = None
    """The temporal preset the pairs of consecutive GT frames are scored under (see
    :mod:`~dispeval_ros.stream.pairs`); None: no pair is scored."""
    pair_gap_ns: int = DEFAULT_PAIR_GAP_NS
    """Frames further apart than this are not paired (with ``temporal`` or ``egomotion``)."""
    egomotion: bool = False
    """Also score each method's ego-motion residual over the same pairs (ground-truth-free
    temporal noise; the camera's motion from the stream's /tf)."""
    flicker: int = 0
    """Frames per flicker window of a static camera (:mod:`~dispeval_ros.stream.flicker`;
    ground-truth-free temporal noise); 0: not scored."""
    names: InitVar[FieldNames | None] = None
    """How the front end names the fields in the errors (not stored; neutral words if None)."""

    def __post_init__(self, names: FieldNames | None) -> None:
        self._normalise()
        self._check_fields(names or NEUTRAL_NAMES)
        if not self.methods:
            raise ConfigurationError("no method given; name at least one NAME=TOPIC")
        topics = list(self.methods.values())
        if len(set(topics)) != len(topics):
            raise ConfigurationError("two methods read the same topic")
        images = (self.left_image_topic, self.right_image_topic)
        others = [
            t for t in images if t and not (self.gt_kind == "none" and t == self.gt_topic)
        ] + [*self.right_views.values(), *self.confidences.values()]
        if len(set(others)) != len(others) or set(others) & {self.gt_topic, *topics}:
            raise ConfigurationError(
                "the image, right-view and confidence topics must differ from each other, from "
                "the ground-truth topic and from the methods' topics"
            )
        if self.gt_topic in topics:
            raise ConfigurationError(
                f"the ground-truth topic {self.gt_topic} is also a method's topic"
            )
        unknown = sorted(set(self.right_views) - set(self.methods))
        if unknown:
            raise ConfigurationError(
                f"right-view disparity topics of unknown methods: {', '.join(unknown)}"
            )
        if self.right_views and not self.gt_free:
            raise ConfigurationError(
                "right-view disparities (for lrc) need the left and right image topics"
            )
        self._check_confidences(names or NEUTRAL_NAMES)
        reserved = [
            m
            for m in self.methods
            if m in (LEFT_IMAGE_KEY, RIGHT_IMAGE_KEY)
            or m.startswith((RIGHT_VIEW_KEY, CONFIDENCE_KEY))
        ]
        if reserved:
            raise ConfigurationError(f"method name '{reserved[0]}' is reserved")
        if self.gt_free:
            GroundTruthFree(self.gt_free_criteria, self.missing)  # checks the criteria
            if "roi" in self.gt_free_criteria:
                raise ConfigurationError(
                    "the ground-truth-free criterion set 'roi' needs a mask: not available on "
                    "streams; choose all, texture"
                )
        self._check_temporal(names or NEUTRAL_NAMES)
        if self.gt_kind == "pointcloud":
            if self.left_info_topic is None:
                raise ConfigurationError(
                    "ground truth from a point cloud needs the left and right CameraInfo topics "
                    "(the left camera's R and P, and the baseline)"
                )
            CloudFilter.parse(self.cloud_filter)
            if self.extrinsic is not None:
                rigid_matrix(self.extrinsic, "the LiDAR extrinsic")

    def _check_confidences(self, names: FieldNames) -> None:
        """Confidences of known methods, scored against a ground truth, in known conventions."""
        for field_name in ("confidences", "confidence_presets"):
            unknown = sorted(set(getattr(self, field_name)) - set(self.methods))
            if unknown:
                raise names.error(
                    f"{names.of(field_name)}: no method is named {', '.join(unknown)} (methods: "
                    f"{', '.join(self.methods)})",
                    field_name,
                )
        extra = sorted(set(self.confidence_presets) - set(self.confidences))
        if extra:
            raise names.error(
                f"{names.of('confidence_presets')}: {', '.join(extra)} has no confidence topic "
                f"(give it in {names.of('confidences')})",
                "confidence_presets",
            )
        if self.confidences and not self.has_gt:
            raise names.error(
                f"{names.of('confidences')}: sparsification curves rank the true error, so they "
                "need a ground truth (gt_kind is none)",
                "confidences",
            )

    def _check_temporal(self, names: FieldNames) -> None:
        """A known preset, a positive pair gap, ground truth to pair, a camera to move."""
        if self.egomotion and self.left_info_topic is None:
            raise names.error(
                f"{names.of('egomotion')} moves each estimate by the camera's motion: give "
                f"{names.of('left_info_topic', 'right_info_topic')} (its principal point and "
                "frame)",
                "egomotion",
            )
        if (self.egomotion or self.flicker) and not self.pair_gap_ns > 0:
            raise names.error(
                f"{names.of('pair_gap_ns')} must be > 0, got {self.pair_gap_ns / 1e6:g} ms",
                "pair_gap_ns",
            )
        if not (isinstance(self.flicker, int) and (self.flicker == 0 or self.flicker >= 2)):
            raise names.error(
                f"{names.of('flicker')} must be 0 (off) or a window of at least 2 frames (the "
                f"spread of one frame is undefined), got {self.flicker!r}",
                "flicker",
            )
        if self.temporal is None:
            return
        if self.temporal not in PRESETS:
            raise names.error(
                f"{names.of('temporal')} must be one of {', '.join(PRESETS)}, "
                f"got '{self.temporal}'",
                "temporal",
            )
        if not self.has_gt:
            raise names.error(
                f"{names.of('temporal')} scores pairs of ground-truth frames: give the ground "
                "truth",
                "temporal",
            )
        if not self.pair_gap_ns > 0:
            raise names.error(
                f"{names.of('pair_gap_ns')} must be > 0, got {self.pair_gap_ns / 1e6:g} ms",
                "pair_gap_ns",
            )

    def _check_fields(self, names: FieldNames) -> None:
        """The rules the front ends share, worded with the front end's names (``names``)."""
        if self.gt_kind not in GT_KINDS:
            raise names.error(
                f"{names.of('gt_kind')} must be one of {', '.join(GT_KINDS)}, got '{self.gt_kind}'",
                "gt_kind",
            )
        for left, right in (
            ("left_image_topic", "right_image_topic"),
            ("left_info_topic", "right_info_topic"),
        ):
            if (getattr(self, left) is None) != (getattr(self, right) is None):
                raise names.error(f"give both {names.of(left, right)}, or neither", left)
        if self.gt_kind == "none" and (
            self.left_image_topic is None or self.left_image_topic != self.gt_topic
        ):
            raise names.error(
                f"{names.of('gt_kind')} is none: give "
                f"{names.of('left_image_topic', 'right_image_topic')} (without ground truth the "
                "left image is the frame clock, and the ground-truth-free measures need them)",
                "left_image_topic",
            )
        if self.gt_kind != "none" and not self.gt_topic:
            raise names.error(
                f"{names.of('gt_topic')} is empty: name the ground-truth topic", "gt_topic"
            )
        others = {
            self.gt_topic,
            self.left_image_topic,
            self.right_image_topic,
            *self.methods.values(),
            *self.right_views.values(),
            *self.confidences.values(),
        }
        for info in ("left_info_topic", "right_info_topic"):
            topic = getattr(self, info)
            if topic is not None and topic in others:  # else its type check would be skipped
                raise names.error(
                    f"{names.of(info)} {topic} is also the ground-truth, an image or a "
                    "disparity topic: name the sensor_msgs/CameraInfo topic",
                    info,
                )

    def _normalise(self) -> None:
        """Plain dicts and tuples, whatever was given: equal configurations compare equal.

        So :meth:`from_record` gives back a configuration equal to the one stored.
        """
        criteria = self.criteria
        fixed: dict[str, object] = {
            "methods": dict(self.methods),
            "criteria": (criteria,) if isinstance(criteria, str) else tuple(criteria),
            "measures": None if self.measures is None else tuple(self.measures),
            "right_views": dict(self.right_views),
            "confidences": dict(self.confidences),
            "confidence_presets": confidence_presets(self.confidences, self.confidence_presets),
            "gt_free_criteria": tuple(self.gt_free_criteria),
            "extrinsic": None if self.extrinsic is None else tuple(self.extrinsic),
        }
        for name, value in fixed.items():
            object.__setattr__(self, name, value)

    @classmethod
    def from_record(cls, record: Mapping[str, Any]) -> CoreConfig:
        """The configuration :meth:`as_record` stored (its inverse).

        Keys the record leaves out (no point cloud, no images) keep their defaults.
        """
        left_info, right_info = (record.get("camera_info") or [None, None])[:2]
        left_image, right_image = (record.get("images") or [None, None])[:2]
        options: dict[str, Any] = {
            key: record[key]
            for key in (
                "gt_kind",
                "gt_scale",
                "missing",
                "delta",
                "mu",
                "tolerance_ns",
                "lateness_ns",
                "temporal",
                "pair_gap_ns",
                "egomotion",
                "flicker",
            )
            if record.get(key) is not None
        }
        if record.get("cloud_filter") is not None:  # point-cloud GT
            options["cloud_filter"] = str(record["cloud_filter"])
        if record.get("extrinsic"):
            options["extrinsic"] = tuple(float(v) for v in record["extrinsic"])
        for key in ("criteria", "measures", "gt_free_criteria"):
            if record.get(key):
                options[key] = tuple(record[key])
        return cls(
            methods=dict(record["methods"]),
            gt_topic=record["gt_topic"],
            left_info_topic=left_info,
            right_info_topic=right_info,
            left_image_topic=left_image,
            right_image_topic=right_image,
            right_views=dict(record.get("right_views") or {}),
            confidences=dict(record.get("confidences") or {}),
            confidence_presets=dict(record.get("confidence_presets") or {}),
            **options,
        )

    @property
    def pointcloud(self) -> bool:
        """Whether the ground truth is a LiDAR point cloud."""
        return self.gt_kind == "pointcloud"

    @property
    def gt_free(self) -> bool:
        """Whether the ground-truth-free measures are scored (both image topics given)."""
        return self.left_image_topic is not None and self.right_image_topic is not None

    @property
    def has_gt(self) -> bool:
        """Whether a ground truth is scored (kind other than ``none``)."""
        return self.gt_kind != "none"

    @property
    def scored_measures(self) -> tuple[str, ...]:
        """Every measure a frame's scores carry: the GT ones, then the GT-free ones."""
        gt = tuple(self.evaluator().measures) if self.has_gt else ()
        free = GT_FREE_SCORED if self.gt_free else ()
        return tuple(dict.fromkeys((*gt, *free)))

    def auxiliary(self) -> dict[str, str]:
        """Join key → topic of the streams joined with each frame beside the methods."""
        keys: dict[str, str] = {}
        if self.gt_free and self.has_gt and self.left_image_topic is not None:
            keys[LEFT_IMAGE_KEY] = self.left_image_topic
        if self.gt_free and self.right_image_topic is not None:
            keys[RIGHT_IMAGE_KEY] = self.right_image_topic
        keys.update({RIGHT_VIEW_KEY + name: topic for name, topic in self.right_views.items()})
        keys.update({CONFIDENCE_KEY + name: topic for name, topic in self.confidences.items()})
        return keys

    @property
    def tf_topic(self) -> str | None:
        """The static transforms topic read (point-cloud GT without an explicit extrinsic)."""
        return TF_STATIC_TOPIC if self.pointcloud and self.extrinsic is None else None

    @property
    def topics(self) -> dict[str, str]:
        """Every subscribed topic → the message type expected on it.

        Calibration topics come first: a front end that serves its readers in this order
        takes a frame's CameraInfo and transforms before the messages that complete it.
        """
        expected: dict[str, str] = {}
        if self.left_info_topic and self.right_info_topic:
            expected[self.left_info_topic] = CAMERA_INFO_TYPE
            expected[self.right_info_topic] = CAMERA_INFO_TYPE
        if self.tf_topic:
            expected[self.tf_topic] = TF_TYPE
        if self.egomotion:  # the camera's motion: its mount (static) and the motion over time
            expected[TF_STATIC_TOPIC] = TF_TYPE
            expected[TF_TOPIC] = TF_TYPE
        expected[self.gt_topic] = POINT_CLOUD_TYPE if self.pointcloud else IMAGE_TYPE
        expected.update(dict.fromkeys(self.methods.values(), DISPARITY_TYPE))
        if self.left_image_topic and self.right_image_topic:
            expected[self.left_image_topic] = IMAGE_TYPE
            expected[self.right_image_topic] = IMAGE_TYPE
        expected.update(dict.fromkeys(self.right_views.values(), DISPARITY_TYPE))
        expected.update(dict.fromkeys(self.confidences.values(), IMAGE_TYPE))
        return expected

    def as_record(self) -> dict[str, object]:
        """The configuration as plain values (stored with results, compared on --resume)."""
        return {
            "methods": dict(self.methods),
            "gt_topic": self.gt_topic,
            "gt_kind": self.gt_kind,
            "gt_scale": self.gt_scale,
            "camera_info": [self.left_info_topic, self.right_info_topic],
            "criteria": list(self.criteria),
            "measures": list(self.measures or []),
            "missing": self.missing,
            "delta": self.delta,
            "mu": self.mu,
            "tolerance_ns": self.tolerance_ns,
            "lateness_ns": self.lateness_ns,
            "lateness_clock": "arrival",  # not resumed onto results waited in stamp time
            **(
                {"extrinsic": list(self.extrinsic or []), "cloud_filter": self.cloud_filter}
                if self.pointcloud
                else {}
            ),
            **(
                {
                    "images": [self.left_image_topic, self.right_image_topic],
                    "right_views": dict(self.right_views),
                    "gt_free_criteria": list(self.gt_free_criteria),
                }
                if self.gt_free
                else {}
            ),
            # only when pairs are scored: records of runs without them are unchanged
            **(
                {"temporal": self.temporal, "pair_gap_ns": self.pair_gap_ns}
                if self.temporal is not None or self.egomotion or self.flicker
                else {}
            ),
            **({"egomotion": True} if self.egomotion else {}),
            **({"flicker": self.flicker} if self.flicker else {}),
            **(
                {
                    "confidences": dict(self.confidences),
                    "confidence_presets": dict(self.confidence_presets),
                }
                if self.confidences
                else {}
            ),
        }

    def ground_truth_free(self) -> GroundTruthFree | None:
        """The ground-truth-free scorer (None without image topics)."""
        if not self.gt_free:
            return None
        return GroundTruthFree(self.gt_free_criteria, self.missing)

    def confidence_scorers(self, evaluator: Evaluator) -> dict[str, ConfidenceScorer]:
        """Each method with a confidence topic → its scorer (``evaluator``: the run's)."""
        return {
            method: ConfidenceScorer(evaluator, parse_preset(self.confidence_presets[method]))
            for method in self.confidences
        }

    def pair_stage(self) -> PairStage | None:
        """The stage scoring consecutive frames' pairs (None without ``temporal``)."""
        if self.temporal is None and not self.egomotion:
            return None
        motion = EgoMotionOptions() if self.egomotion else None
        drift = DriftOptions.of_run(self.missing, self.delta) if self.pointcloud else None
        return PairStage(self.evaluator(), self.temporal, self.pair_gap_ns, motion, drift)

    def flicker_stage(self) -> FlickerStage | None:
        """The stage scoring flicker windows (None without ``flicker``)."""
        if not self.flicker:
            return None
        return FlickerStage(self.flicker, self.pair_gap_ns, EgoMotionOptions())

    def evaluator(self) -> Evaluator:
        """The core evaluator these options describe (measures default to the summable ones).

        Unused without ground truth (``gt_kind`` ``none``).

        LiDAR GT gets metric depth ranges (0-10, 10-30, 30+ m), the sparse boundary rule and
        the depth-domain measures by default.
        """
        measures = self.measures if self.measures is not None else default_measures(self.pointcloud)
        if not self.pointcloud:
            return Evaluator(self.criteria, measures, self.missing, self.delta, self.mu)
        return Evaluator(
            self.criteria,
            measures,
            self.missing,
            self.delta,
            self.mu,
            boundary_mode="sparse",
            depth_ranges=LIDAR_DEPTH_RANGES,
        )


LIVE_CONFIDENCE_REFUSAL = (
    "confidence maps are scored from recordings only for now (dispeval bag): the live front "
    "ends do not publish or store their curves' sums yet; record the topics and run dispeval bag"
)
"""Why ``dispeval live`` and the ROS evaluator refuse ``confidences`` (one place, one wording)."""


def refuse_live_confidences(config: CoreConfig, names: FieldNames) -> None:
    """A live front end's check: no ``confidences`` (their sums would be lost)."""
    if config.confidences:
        raise names.error(f"{names.of('confidences')}: {LIVE_CONFIDENCE_REFUSAL}", "confidences")


def confidence_presets(
    confidences: Mapping[str, str], presets: Mapping[str, str]
) -> dict[str, str]:
    """Every method of ``confidences`` → its preset written out (the default filled in).

    A preset that is not one is a :class:`ConfigurationError` naming it (see
    :func:`~dispeval_ros.core.confidence.parse_preset`).
    """
    written = {method: parse_preset(text).text() for method, text in presets.items()}
    return {method: written.get(method, DEFAULT_PRESET) for method in confidences} | written


def field_default(record: type, name: str) -> Any:
    """The default of a dataclass field: the one value front ends show as their default."""
    for item in dataclasses.fields(record):
        if item.name == name:
            if item.default is not dataclasses.MISSING:
                return item.default
            if item.default_factory is not dataclasses.MISSING:
                return item.default_factory()
    raise KeyError(f"{record.__name__} has no default for '{name}'")


def core_default(name: str) -> Any:
    """The default of a :class:`CoreConfig` field (see :func:`field_default`)."""
    return field_default(CoreConfig, name)


def default_measures(pointcloud: bool) -> tuple[str, ...]:
    """The measures scored when none are named: the summable ones, and LiDAR's depth ones.

    Quantiles are opt-in for streams: not summable over frames, not cheap.
    """
    return (*SEQUENCE_MEASURES, *DEPTH_MEASURES) if pointcloud else SEQUENCE_MEASURES
