"""One configuration: CoreConfig's record round trip, and every front end's defaults pinned to it.

The defaults of the evaluation options are written once, as CoreConfig's field defaults; the
argparse options of ``dispeval bag``/``live``, the ROS parameter table and the config YAML files
either derive theirs from it or are checked against it here. The topics read are one list
(:attr:`CoreConfig.topics`), used by the readers, the checks and the provenance.
"""

from __future__ import annotations

import inspect
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from dispeval_ros.cli import streams
from dispeval_ros.cli.main import build_parser
from dispeval_ros.core import Evaluator
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.offline.records import stream_topics
from dispeval_ros.ros import param_table, params
from dispeval_ros.stream.config import CoreConfig, core_default

ROOT = Path(__file__).resolve().parents[2]
NS = 1_000_000_000
METHODS = {"sgbm": "/stereo/sgbm/disparity", "bm": "/stereo/bm/disparity"}
INFOS = {"left_info_topic": "/left/camera_info", "right_info_topic": "/right/camera_info"}
IMAGES = {"left_image_topic": "/left/image_rect", "right_image_topic": "/right/image_rect"}

FIELDS: dict[str, tuple[str, str, Any]] = {
    # CoreConfig field: (ROS parameter, argparse dest of bag/live, how their default becomes it)
    "gt_kind": ("gt_kind", "gt_kind", str),
    "cloud_filter": ("cloud_filter", "cloud_filter", str),
    "criteria": ("criteria", "criteria", tuple),
    "missing": ("missing", "missing", str),
    "delta": ("delta", "delta", float),
    "mu": ("mu", "mu", float),
    "gt_free_criteria": ("gt_free_criteria", "gt_free_criteria", tuple),
}
TIMES = {"tolerance_ns": ("sync_tolerance", "tolerance"), "lateness_ns": ("lateness", "lateness")}
"""Time fields: the ROS parameter in s, the option in ms."""
YAML_SAMPLE_VALUES = {"methods", "gt_topic", "left_camera_info", "right_camera_info"}
"""Parameters config/evaluator.yaml sets to the sample bag's topics instead of the defaults."""


def fixture_configs() -> list[CoreConfig]:
    """The configurations the stream and bag tests build (test_stream_core, test_bag_*,
    test_lidar_streams, test_gtfree_streams, sample_feed), and variations of each option."""
    cloud = {"gt_topic": "/lidar/points", "gt_kind": "pointcloud", **INFOS}
    return [
        CoreConfig(methods={m: f"/{m}" for m in "abc"}, gt_topic="/gt"),
        CoreConfig(methods={"a": "/a/disparity", "b": "/b/disparity"}, gt_topic="/gt", **INFOS),
        CoreConfig(methods=METHODS, **cloud),
        CoreConfig(methods=METHODS, **cloud, extrinsic=tuple(np.eye(4).reshape(-1))),
        CoreConfig(methods=METHODS, **cloud, cloud_filter="0", measures=("bmp", "mae_z")),
        CoreConfig(methods=METHODS, gt_topic="/gt", **INFOS, **IMAGES),
        CoreConfig(methods=METHODS, gt_topic=IMAGES["left_image_topic"], gt_kind="none", **IMAGES),
        CoreConfig(
            methods=METHODS,
            gt_topic="/gt",
            gt_kind="depth",
            gt_scale=1000.0,
            criteria=["all"],
            measures=["bmp", "sze"],
            missing="ignore",
            delta=3.0,
            mu=0.5,
            tolerance_ns=5_000_000,
            lateness_ns=250_000_000,
            **IMAGES,
            right_views={"sgbm": "/stereo/sgbm/right"},
            gt_free_criteria=("texture",),
        ),
    ]


def cli_config(argv: list[str]) -> CoreConfig:
    args = build_parser().parse_args(["bag", "drive.mcap", *argv])
    return streams.core_config(args, "bags")


def cli_configs() -> list[CoreConfig]:
    methods = [a for name, topic in METHODS.items() for a in ("--method", f"{name}={topic}")]
    infos = ["--camera-info", INFOS["left_info_topic"], INFOS["right_info_topic"]]
    images = ["--left-image", IMAGES["left_image_topic"], "--right-image", "/right/image_rect"]
    return [
        cli_config(["--gt", "/gt", *methods]),
        cli_config(["--gt", "/gt", *methods, *infos, "--gt-kind", "depth", "--tolerance", "5"]),
        cli_config(["--gt-cloud", "/lidar/points", *methods, *infos]),
        cli_config([*images, *methods, "--right-view", "bm=/bm/right"]),
        cli_config(["--gt", "/gt", *images, *methods, "--criteria", "all", "--lateness", "50"]),
    ]


def ros_values(**changes: Any) -> dict[str, Any]:
    values = {p.name: p.empty_default for p in param_table.EVALUATOR_PARAMETERS}
    values["methods"] = tuple(f"{name}:{topic}" for name, topic in METHODS.items())
    values["gt_topic"] = "/gt"
    return {**values, **changes}


def ros_configs() -> list[CoreConfig]:
    images = {"left_image_topic": "/left/image_rect", "right_image_topic": "/right/image_rect"}
    return [
        params.core_config(ros_values()),
        params.core_config(ros_values(gt_kind="none", gt_topic="", **images)),
        params.core_config(
            ros_values(
                gt_kind="pointcloud",
                left_camera_info="/l",
                right_camera_info="/r",
                lidar_extrinsic="0.5 0 0 0 0 0 1",  # x y z qx qy qz qw
            )
        ),
    ]


@pytest.mark.parametrize(
    "config", [*fixture_configs(), *cli_configs(), *ros_configs()], ids=lambda c: c.gt_kind
)
def test_from_record_inverts_as_record(config: CoreConfig) -> None:
    assert CoreConfig.from_record(config.as_record()) == config


_TOPIC = st.from_regex(r"/[a-z]{1,3}(/[a-z]{1,3})?", fullmatch=True)
_NAME = st.from_regex(r"[a-z][a-z0-9_]{0,4}", fullmatch=True)


@st.composite
def configurations(draw: st.DrawFn) -> CoreConfig:
    """Valid configurations with every option drawn (the unused ones left at their defaults)."""
    kind = draw(st.sampled_from(("disparity", "depth", "pointcloud", "none")))
    methods = draw(st.dictionaries(_NAME, _TOPIC, min_size=1, max_size=3))
    options: dict[str, Any] = {
        "criteria": draw(
            st.lists(
                st.sampled_from(("all", "visibility", "depth")), min_size=1, max_size=3, unique=True
            )
        ),
        "measures": draw(
            st.none()
            | st.lists(
                st.sampled_from(("bmp", "mae", "sze", "d1")), min_size=1, max_size=3, unique=True
            )
        ),
        "missing": draw(st.sampled_from(("interpolate", "thesis", "ignore"))),
        "delta": draw(st.floats(0.1, 10.0)),
        "mu": draw(st.floats(0.001, 1.0)),
        "tolerance_ns": draw(st.integers(0, 10 * NS)),
        "lateness_ns": draw(st.integers(0, 10 * NS)),
        "gt_scale": draw(st.none() | st.floats(1.0, 1000.0)),
    }
    if draw(st.booleans()) or kind == "pointcloud":
        options.update(left_info_topic=draw(_TOPIC), right_info_topic=draw(_TOPIC))
    if kind == "pointcloud":
        options["cloud_filter"] = draw(st.sampled_from(("0", "7,0.1", "5,0.2")))
        if draw(st.booleans()):
            options["extrinsic"] = tuple(float(v) for v in np.eye(4).reshape(-1))
    if draw(st.booleans()) or kind == "none":
        options.update(left_image_topic=draw(_TOPIC), right_image_topic=draw(_TOPIC))
        views = draw(st.dictionaries(st.sampled_from(sorted(methods)), _TOPIC, max_size=2))
        options["right_views"] = views
        options["gt_free_criteria"] = draw(
            st.lists(st.sampled_from(("all", "texture")), min_size=1, max_size=2, unique=True)
        )
    gt_topic = options["left_image_topic"] if kind == "none" else draw(_TOPIC)
    try:
        return CoreConfig(methods=methods, gt_topic=gt_topic, gt_kind=kind, **options)
    except ConfigurationError:  # e.g. two streams drawn on one topic
        assume(False)
        raise


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(configurations())
def test_every_configuration_survives_its_record(config: CoreConfig) -> None:
    assert CoreConfig.from_record(config.as_record()) == config


def test_ros_parameters_default_to_the_core_configuration() -> None:
    table = {p.name: p for p in param_table.EVALUATOR_PARAMETERS}
    for field, (name, _dest, as_field) in FIELDS.items():
        assert as_field(table[name].default) == core_default(field), name
    for field, (name, _dest) in TIMES.items():
        assert round(table[name].default * NS) == core_default(field), name
    assert params.core_config(ros_values()) == CoreConfig(methods=METHODS, gt_topic="/gt")


def test_cli_options_default_to_the_core_configuration() -> None:
    for command in ("bag", "live"):
        args = build_parser().parse_args(
            [command, *(["drive.mcap"] if command == "bag" else []), "--method", "a=/a"]
        )
        for field, (_name, dest, as_field) in FIELDS.items():
            assert as_field(getattr(args, dest)) == core_default(field), (command, dest)
        for field, (_name, dest) in TIMES.items():
            assert round(getattr(args, dest) * 1_000_000) == core_default(field), dest
    config = cli_config(["--gt", "/gt", "--method", "a=/a"])
    assert config.measures is not None  # the CLI names the sequence measures explicitly
    assert config == CoreConfig(methods={"a": "/a"}, gt_topic="/gt", measures=config.measures)


def test_the_core_configuration_defaults_are_the_evaluators() -> None:
    signature = inspect.signature(Evaluator)
    for name in ("criteria", "missing", "delta", "mu"):
        assert tuple(np.atleast_1d(signature.parameters[name].default)) == tuple(
            np.atleast_1d(core_default(name))
        ), name


def yaml_parameters(name: str) -> dict[str, Any]:
    document = yaml.safe_load((ROOT / "config" / name).read_text())
    (node,) = document.values()
    return dict(node["ros__parameters"])


def commented_parameters(name: str) -> set[str]:
    text = (ROOT / "config" / name).read_text()
    return set(re.findall(r"^\s*#\s*([a-z_]+):", text, re.MULTILINE))


@pytest.mark.parametrize(
    ("name", "table"),
    [
        ("evaluator.yaml", param_table.EVALUATOR_PARAMETERS),
        ("summarizer.yaml", param_table.SUMMARIZER_PARAMETERS),
    ],
)
def test_yaml_files_are_the_parameter_table(name: str, table: tuple[Any, ...]) -> None:
    """Every parameter is in the file (set, or commented out when its default is an empty
    array), with the table's default unless it names the sample bag's topics."""
    values = yaml_parameters(name)
    rows = {p.name: p for p in table}
    assert set(values) <= set(rows), set(values) - set(rows)
    assert set(rows) == set(values) | (commented_parameters(name) & set(rows))
    for key, value in values.items():
        if key in YAML_SAMPLE_VALUES:
            continue
        default = rows[key].default
        assert (tuple(value) if isinstance(value, list) else value) == default, key


def test_the_provenance_lists_every_topic_the_readers_open() -> None:
    for config in fixture_configs():
        assert set(stream_topics(config)) == set(config.topics)
        assert stream_topics(config)[: 1 + len(config.methods)] == [
            config.gt_topic,
            *config.methods.values(),
        ]


def test_ros_and_dds_publish_on_the_same_topics() -> None:
    pytest.importorskip("rclpy")
    from dispeval_ros.dds import wire
    from dispeval_ros.ros import evaluator, summarizer

    assert evaluator.SCORES_TOPIC == summarizer.SCORES_TOPIC == wire.SCORES_TOPIC
    assert summarizer.GROUPS_TOPIC == wire.GROUPS_TOPIC
    assert wire.vector_topic("sgbm") == evaluator.method_topic("sgbm", "vector")


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small synthetic drive with images, camera infos, GT, LiDAR scans and /tf_static."""
    from dispeval_ros.cli.main import main

    path = tmp_path_factory.mktemp("drive") / "drive.mcap"
    argv = ["make-bag", str(path), "--storage", "mcap", "--frames", "3"]
    assert main([*argv, "--width", "320", "--height", "96"]) == 0
    return path


@pytest.mark.parametrize(
    "ground_truth",
    [
        ["--gt-cloud", "/lidar/points"],
        ["--left-image", "/stereo/left/image_rect", "--right-image", "/stereo/right/image_rect"],
    ],
    ids=["lidar", "gt-free"],
)
def test_the_provenance_hashes_every_stream_read(
    drive: Path, ground_truth: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The LiDAR run's /tf_static, the GT-free run's right image: hashed like the rest."""
    import json

    from dispeval_ros.cli.main import main
    from dispeval_ros.io.provenance import stream_digests

    topics = ["--method", "sgbm=/stereo/sgbm/disparity"]
    topics += ["--camera-info", "/stereo/left/camera_info", "/stereo/right/camera_info"]
    argv = ["bag", str(drive), *ground_truth, *topics, "--out", str(tmp_path), "--quiet"]
    assert main([*argv, "--json"]) == 0
    record = json.loads(capsys.readouterr().out)["provenance"]
    config = CoreConfig.from_record(record["configuration"])
    (streams,) = record["inputs"]["streams"].values()
    read = set(config.topics)
    assert "/tf_static" in read or "/stereo/right/image_rect" in read
    assert set(streams["topics"]) == read
    assert streams["topics"] == stream_digests(drive, stream_topics(config))


def test_live_options_are_the_live_cores_and_the_ros_tables() -> None:
    """Queue size, summary period and objectives: one default for ``live``, ROS and DDS."""
    from dispeval_ros.dds.evaluator import DdsEvaluator
    from dispeval_ros.stream.config import QUEUE_SIZE, field_default
    from dispeval_ros.stream.runner import LiveEvaluator
    from dispeval_ros.stream.summarizer import SummarizerConfig

    assert inspect.signature(LiveEvaluator).parameters["queue_size"].default == QUEUE_SIZE
    assert inspect.signature(DdsEvaluator).parameters["queue_size"].default == QUEUE_SIZE
    args = build_parser().parse_args(["live", "--method", "a=/a", "--gt", "/gt"])
    rows = {p.name: p.default for p in param_table.EVALUATOR_PARAMETERS}
    rows.update({p.name: p.default for p in param_table.SUMMARIZER_PARAMETERS})
    assert args.queue_size == rows["queue_size"] == QUEUE_SIZE
    every_n = field_default(SummarizerConfig, "every_n")
    assert args.summary_every == rows["summary_every"] == every_n
    granularity = field_default(SummarizerConfig, "granularity")
    assert args.objectives == rows["objectives"] == granularity


def test_the_example_yaml_names_only_table_parameters() -> None:
    """stereo_image_proc.yaml overrides some values on purpose; its names and types hold."""
    document = yaml.safe_load((ROOT / "config" / "stereo_image_proc.yaml").read_text())
    tables = {
        "dispeval_evaluator": param_table.EVALUATOR_PARAMETERS,
        "dispeval_summarizer": param_table.SUMMARIZER_PARAMETERS,
    }
    types = {"bool": bool, "integer": int, "double": float, "string": str, "string[]": list}
    for node, table in tables.items():
        rows = {p.name: p for p in table}
        for key, value in document[node]["ros__parameters"].items():
            assert isinstance(value, types[rows[key].kind]), (node, key)
