"""A record of how each number was made: version, configuration hash, input digests, in every output."""

from __future__ import annotations

import hashlib
import json
import struct
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import blake3
import numpy as np
import pytest

from dispeval_ros import __version__
from dispeval_ros.cli.main import main
from dispeval_ros.core.protocols import PROTOCOLS, config_sha256, get_protocol
from dispeval_ros.errors import InputError
from dispeval_ros.io import provenance, write_pfm
from dispeval_ros.io.provenance import same_stream, stream_digests, verify_streams
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


HASHES: dict[str, Callable[[], Any]] = {"blake3": blake3.blake3, "sha256": hashlib.sha256}


def raw_digest(bag: Path, topic: str, algorithm: str = "blake3") -> tuple[str, int]:
    """The hash of (log time, length, bytes) of each serialized message, read with rosbags."""
    from rosbags.highlevel import AnyReader

    digest, count = HASHES[algorithm](), 0
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        for _c, log_ns, raw in reader.messages(connections):
            digest.update(struct.pack("<qQ", log_ns, len(raw)) + bytes(raw))
            count += 1
    return digest.hexdigest(), count


def test_stream_digests_are_the_serialized_messages(drives: dict[str, Path]) -> None:
    topics = [GT_TOPIC, disparity_topic("sgbm"), LEFT_INFO]
    for algorithm in ("blake3", "sha256"):  # new records, and those made before BLAKE3
        chosen = None if algorithm == "blake3" else algorithm  # the default is BLAKE3
        digests = {
            fmt: stream_digests(path, topics, algorithm=chosen) for fmt, path in drives.items()
        }
        for topic in topics:
            want, count = raw_digest(drives["rosbag2-sqlite3"], topic, algorithm)
            assert count == 4
            for fmt in drives:  # CDR is CDR whatever the storage
                assert digests[fmt][topic] == {algorithm: want, "messages": 4}, (fmt, topic)
        assert digests["mcap"][GT_TOPIC] != digests["mcap"][LEFT_INFO]


class ListedSource:
    """A bag reduced to what the digests read of it: its messages, serialized, in order."""

    format = "mcap"

    def __init__(self, messages: list[tuple[str, int, bytes]]) -> None:
        self.messages = messages
        self.topics = {topic: None for topic, _, _ in messages}

    def serialized_messages(self, topics: list[str]) -> Iterator[tuple[str, int, bytes]]:
        return iter([m for m in self.messages if m[0] in topics])


def listed_digest(messages: list[tuple[str, int, bytes]], algorithm: str = "blake3") -> str:
    """The definition written out: per message, log time and length (<q, <Q), then bytes."""
    digest = HASHES[algorithm]()
    for _topic, log_ns, raw in messages:
        digest.update(log_ns.to_bytes(8, "little", signed=True))
        digest.update(len(raw).to_bytes(8, "little") + raw)
    return digest.hexdigest()


def test_a_changed_dropped_or_reordered_message_changes_the_digest() -> None:
    base = [("/a", 100, b"first"), ("/b", 150, b"other"), ("/a", 200, b"second"), ("/a", 300, b"x")]
    variants = {
        "as recorded": base,
        "one byte changed": [base[0], base[1], ("/a", 200, b"secoNd"), base[3]],
        "one log time changed": [base[0], base[1], ("/a", 201, b"second"), base[3]],
        "one dropped": [base[0], base[1], base[3]],
        "two swapped": [("/a", 100, b"second"), base[1], ("/a", 200, b"first"), base[3]],
        "a byte moved to the next message": [
            base[0],
            base[1],
            ("/a", 200, b"secon"),
            ("/a", 300, b"dx"),
        ],
    }
    seen: dict[str, str] = {}
    for algorithm in HASHES:
        for name, messages in variants.items():
            digests, damage = provenance.digests_to_damage(
                Path("listed"),
                ["/a", "/b"],
                ListedSource(messages),
                algorithm,  # type: ignore[arg-type]
            )
            assert damage is None
            entry = digests["/a"]
            on_a = [m for m in messages if m[0] == "/a"]
            assert entry == {algorithm: listed_digest(on_a, algorithm), "messages": len(on_a)}
            assert digests["/b"][algorithm] == listed_digest([base[1]], algorithm)  # untouched
            seen[f"{algorithm} {name}"] = str(entry[algorithm])
    assert len(set(seen.values())) == len(seen), seen


def test_digests_of_different_algorithms_are_never_compared() -> None:
    messages = [("/a", 100, b"first"), ("/a", 200, b"second")]
    digests = {
        algorithm: provenance.digests_to_damage(
            Path("listed"),
            ["/a"],
            ListedSource(messages),
            algorithm,  # type: ignore[arg-type]
        )[0]["/a"]
        for algorithm in HASHES
    }
    assert same_stream(digests["blake3"], dict(digests["blake3"])) is True
    assert same_stream(digests["sha256"], dict(digests["sha256"])) is True
    assert same_stream(digests["blake3"], digests["sha256"]) is None  # not "equal", not "differ"
    assert same_stream(digests["sha256"], {**digests["sha256"], "messages": 3}) is False
    changed = {"sha256": listed_digest(messages[:1], "sha256"), "messages": 2}
    assert same_stream(digests["sha256"], changed) is False
    with pytest.raises(ValueError, match="names one of"):
        same_stream({"md5": "00", "messages": 2}, digests["sha256"])


def test_without_blake3_the_digests_are_sha256_and_say_so(
    drives: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A ROS build without pip (blake3 has no rosdep key) records sha256 under its name."""
    record = {"topics": stream_digests(drives["mcap"], [GT_TOPIC])}  # made where blake3 is
    monkeypatch.setattr(provenance, "HASHERS", {"sha256": hashlib.sha256})
    with pytest.raises(
        InputError, match=r"drive.mcap: its digests are blake3, .*pip install blake3"
    ):
        verify_streams(drives["mcap"], record)  # one line, not a KeyError
    assert provenance.stream_algorithm() == "sha256"
    got = stream_digests(drives["mcap"], [GT_TOPIC])
    assert got == {
        GT_TOPIC: {
            "sha256": raw_digest(drives["rosbag2-mcap"], GT_TOPIC, "sha256")[0],
            "messages": 4,
        }
    }


def test_stored_records_of_either_algorithm_verify(drives: dict[str, Path]) -> None:
    bag = drives["rosbag2-mcap"]
    topics = [GT_TOPIC, disparity_topic("sgbm"), LEFT_INFO]
    new = {"bag": str(bag), "topics": stream_digests(bag, topics)}
    old = {"bag": str(bag), "topics": stream_digests(bag, topics, algorithm="sha256")}
    mixed = {"bag": str(bag), "topics": {**new["topics"], LEFT_INFO: old["topics"][LEFT_INFO]}}
    for record in (new, old, mixed):
        assert verify_streams(bag, record) == dict.fromkeys(topics, True)
    for fmt, other in drives.items():  # the same recording in another storage verifies too
        assert all(verify_streams(other, old).values()), fmt
    tampered = json.loads(json.dumps(old))
    tampered["topics"][GT_TOPIC]["messages"] = 3
    verdict = verify_streams(bag, tampered)
    assert verdict == {**dict.fromkeys(topics, True), GT_TOPIC: False}
    stopped = {**new, "read_up_to": "somewhere"}  # the bag now reads to its end: not the same
    assert not any(verify_streams(bag, stopped).values())


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
    assert topics[GT_TOPIC]["blake3"] == raw_digest(drives["rosbag2-mcap"], GT_TOPIC)[0]
    assert all(
        verify_streams(drives["rosbag2-mcap"], record["inputs"]["streams"]["mcap_folder"]).values()
    )
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
