"""``dispeval info`` shows /tf's edges and spans, /tf_static's edges and the camera's motion."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dispeval_ros.cli.main import main
from dispeval_ros.core import Camera
from dispeval_ros.core.transforms import StaticTransform
from dispeval_ros.io.bags import BagWriter
from dispeval_ros.io.encoders import camera_info_to_msg, tf_static_to_msg
from dispeval_ros.offline.make_bag import START_NS, synthetic_frames, write_bag
from dispeval_ros.testbed import StereoMethod

MS = 1_000_000


def _info(capsys: pytest.CaptureFixture[str], bag: Path, *extra: str) -> str:
    capsys.readouterr()
    assert main(["info", str(bag), *extra]) == 0
    return capsys.readouterr().out


def test_a_drive_shows_its_tf(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / "drive"
    write_bag(bag, synthetic_frames(3, 96, 32, 10.0, seed=5), methods=[StereoMethod("bm", "bm")])
    (facts,) = json.loads(_info(capsys, bag, "--json"))["bags"]
    transforms = facts["transforms"]
    assert transforms["tf"] == [
        {
            "parent": "odom",
            "child": "base_link",
            "samples": 3,
            "first_ns": START_NS,
            "last_ns": START_NS + 200 * MS,
        }
    ]
    assert transforms["tf_static"] == [{"parent": "base_link", "child": "stereo_left"}]
    assert transforms["camera_frame"] == "stereo_left"
    assert transforms["ego_motion"] == "the camera frame 'stereo_left' moves through 'odom' on /tf"
    assert transforms["problems"] == []
    assert transforms["tf_messages"] == {"read": 3, "total": 3}
    (tf,) = [t for t in facts["topics"] if t["name"] == "/tf"]
    assert tf["use"] == "(ego-motion)"
    text = _info(capsys, bag)
    assert (
        "/tf odom → base_link: 3 samples, 1700000000.000000000 s to 1700000000.200000000 s "
        "(0.2 s, 10 Hz)"
    ) in text
    assert "/tf_static: base_link → stereo_left\n" in text


def test_bad_tf_is_a_note_per_problem(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / "bad.mcap"
    with BagWriter(bag, "mcap") as writer:
        types = writer.typestore
        info = camera_info_to_msg(types, Camera(100.0, 0.1), 8, 4, START_NS, "cam", False)
        writer.write("/left/camera_info", START_NS, info)
        for order, (stamp, parent, child) in enumerate(
            (
                (START_NS + 100 * MS, "odom", "base_link"),
                (START_NS, "odom", "base_link"),  # logged after a later stamp
                (START_NS + 200 * MS, "map", "base_link"),  # a second parent
            )
        ):
            edge = StaticTransform(parent, child, np.eye(4))
            log = START_NS + (order + 1) * 100 * MS
            writer.write("/tf", log, tf_static_to_msg(types, [edge], stamp))
    (facts,) = json.loads(_info(capsys, bag, "--json"))["bags"]
    transforms = facts["transforms"]
    (edge,) = transforms["tf"]
    assert (edge["samples"], edge["first_ns"], edge["last_ns"]) == (
        2,
        START_NS,
        START_NS + 100 * MS,
    )
    problems = transforms["problems"]
    assert len(problems) == 2
    assert "frame 'base_link' already has the parent 'odom' on /tf" in problems[0]
    assert problems[1] == (
        "/tf odom → base_link: 1 sample(s) logged after a later stamp (out of order; lookups "
        "sort them by stamp)"
    )
    # The camera's frame is in no transform: the reason, naming the frames known.
    assert transforms["ego_motion"] == (
        "the camera frame 'cam' is in no /tf or /tf_static transform; frames known: base_link, odom"
    )
    text = _info(capsys, bag)
    assert "note: /tf odom → base_link: 1 sample(s) logged after a later stamp" in text
    assert "ego-motion: the camera frame 'cam' is in no /tf" in text
