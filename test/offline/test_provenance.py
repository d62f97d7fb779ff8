"""A record of how each number was made: version, configuration hash, input sha256, in every output."""

from __future__ import annotations

import hashlib
import json
import struct
from pathlib import Path

import numpy as np
import pytest

from dispeval_ros import __version__
from dispeval_ros.cli.main import main
from dispeval_ros.core.protocols import PROTOCOLS, config_sha256, get_protocol
from dispeval_ros.io import write_pfm
from dispeval_ros.io.provenance import stream_digests
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline import make_bag
from dispeval_ros.offline.make_bag import GT_TOPIC, LEFT_INFO, RIGHT_INFO, disparity_topic


@pytest.fixture(scope="module")
def drives(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same 4-frame drive as rosbag2 (sqlite3 and MCAP) and as a plain MCAP file."""
    root = tmp_path_factory.mktemp("drives")
    frames = list(make_bag.synthetic_frames(4, 192, 64, 10.0, seed=3))
    names = {"rosbag2-sqlite3": "sqlite", "rosbag2-mcap": "mcap_folder", "mcap": "drive.mcap"}
    for storage, name in names.items():
        make_bag.write_bag(root / name, iter(frames), storage=storage)
    return {storage: root / name for storage, name in names.items()}


def raw_digest(bag: Path, topic: str) -> tuple[str, int]:
    """sha256 of (log time, length, bytes) of each serialized message, read with rosbags."""
    from rosbags.highlevel import AnyReader

    digest, count = hashlib.sha256(), 0
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        for _c, log_ns, raw in reader.messages(connections):
            digest.update(struct.pack("<qQ", log_ns, len(raw)) + bytes(raw))
            count += 1
    return digest.hexdigest(), count


def test_stream_digests_are_the_serialized_messages(drives: dict[str, Path]) -> None:
    topics = [GT_TOPIC, disparity_topic("sgbm"), LEFT_INFO]
    digests = {fmt: stream_digests(path, topics) for fmt, path in drives.items()}
    for topic in topics:
        want, count = raw_digest(drives["rosbag2-sqlite3"], topic)
        assert count == 4
        for fmt in drives:  # CDR is CDR whatever the storage
            assert digests[fmt][topic] == {"sha256": want, "messages": 4}, (fmt, topic)
    assert digests["mcap"][GT_TOPIC] != digests["mcap"][LEFT_INFO]


def test_bag_database_and_summary_carry_provenance(
    drives: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    methods = [f"sgbm={disparity_topic('sgbm')}", f"bm={disparity_topic('bm_fast')}"]
    argv = ["bag", str(drives["rosbag2-mcap"]), "--gt", GT_TOPIC, "--out", str(out), "--quiet"]
    argv += [*(a for m in methods for a in ("--method", m)), "--camera-info", LEFT_INFO, RIGHT_INFO]
    argv += ["--protocol", "kitti2012", "--json"]
    assert main(argv) == 0
    document = json.loads(capsys.readouterr().out)
    record = document["provenance"]
    assert record["version"] == __version__
    assert record["configuration"]["protocol"] == "kitti2012"
    assert record["configuration"]["measures"] == [
        "bad_2",
        "bad_3",
        "bad_4",
        "bad_5",
        "mae",
        "density",
    ]
    assert record["configuration_sha256"] == config_sha256(record["configuration"])
    topics = record["inputs"]["streams"]["mcap_folder"]["topics"]
    assert set(topics) == {
        GT_TOPIC,
        disparity_topic("sgbm"),
        disparity_topic("bm_fast"),
        LEFT_INFO,
        RIGHT_INFO,
    }
    assert topics[GT_TOPIC]["sha256"] == raw_digest(drives["rosbag2-mcap"], GT_TOPIC)[0]
    assert json.loads((out / "summary.json").read_text())["provenance"] == record
    with ResultsStore.open(out) as store:
        assert store.provenance() == record
        assert store.measures()[:4] == ["bad_2", "bad_3", "bad_4", "bad_5"]


def test_store_without_provenance_reads_empty(tmp_path: Path) -> None:
    with ResultsStore.create(tmp_path, {"a": 1}) as store:
        assert store.provenance() == {}
        store.set_provenance({"version": "x", "inputs": {"files": {}}})
        store.set_provenance({"version": "y"})
        assert store.provenance() == {"version": "y", "inputs": {"files": {}}}


def test_eval_json_hashes_every_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gt = np.tile(np.linspace(5, 30, 40, dtype=np.float32), (20, 1))
    write_pfm(tmp_path / "gt.pfm", gt)
    write_pfm(tmp_path / "a.pfm", gt + np.float32(0.5))
    write_pfm(tmp_path / "b.pfm", gt - np.float32(1.5))
    argv = ["eval", "--gt", str(tmp_path / "gt.pfm"), "--est", str(tmp_path / "a.pfm")]
    assert main([*argv, "--est", f"b={tmp_path / 'b.pfm'}", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)["provenance"]
    files = record["inputs"]["files"]
    assert set(files) == {str(tmp_path / n) for n in ("gt.pfm", "a.pfm", "b.pfm")}
    for path, digest in files.items():
        assert digest == hashlib.sha256(Path(path).read_bytes()).hexdigest()
    assert record["configuration"]["missing"] == "interpolate"
    assert record["configuration_sha256"] == config_sha256(record["configuration"])


def test_protocol_hashes_are_stable_and_distinct() -> None:
    hashes = {name: get_protocol(name).sha256() for name in PROTOCOLS}
    assert len(set(hashes.values())) == len(PROTOCOLS)
    assert hashes["kitti2015"] == config_sha256(PROTOCOLS["kitti2015"].record())
