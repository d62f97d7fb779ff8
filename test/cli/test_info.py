"""``dispeval info``: counts, spans and stamp offsets as rosbags reads them; a command that runs."""

from __future__ import annotations

import json
import shlex
from pathlib import Path

import pytest
from refusal_support import assert_refused

from dispeval_ros.cli.info_cmd import method_names
from dispeval_ros.cli.main import main
from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.offline.make_bag import GT_TOPIC, synthetic_frames, write_bag

KITTI_RAW = "kitti-raw-drive-0048/2011_09_26"


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One short drive in each format dispeval writes."""
    root = tmp_path_factory.mktemp("info")
    made = {}
    for storage, name in (
        ("rosbag2-sqlite3", "drive_db3"),
        ("rosbag2-mcap", "drive_mcap"),
        ("mcap", "drive.mcap"),
    ):
        made[storage] = root / name
        write_bag(made[storage], synthetic_frames(3, 96, 32, 10.0, seed=5), storage=storage)
    return made


def info_json(capsys: pytest.CaptureFixture[str], *paths: Path) -> dict:
    capsys.readouterr()
    assert main(["info", *map(str, paths), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def rosbags_facts(path: Path) -> dict[str, tuple[str, int, int, int, int | None, int | None]]:
    """Per topic, as rosbags reads the whole bag: type, count, first/last log time and offsets."""
    from rosbags.highlevel import AnyReader

    facts: dict[str, list] = {}
    with AnyReader([path]) as reader:
        for connection, log_ns, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            offset = log_ns - stamp_ns(msg.header) if hasattr(msg, "header") else None
            entry = facts.setdefault(
                connection.topic, [connection.msgtype, 0, log_ns, log_ns, offset, offset]
            )
            entry[1] += 1
            entry[3], entry[5] = log_ns, offset
    return {topic: tuple(entry) for topic, entry in sorted(facts.items())}


def shown(document: dict) -> dict[str, tuple]:
    return {
        topic["name"]: (
            topic["type"],
            topic["count"],
            topic["first_log_ns"],
            topic["last_log_ns"],
            topic["stamp_offset_ns"]["first"],
            topic["stamp_offset_ns"]["last"],
        )
        for topic in document["topics"]
    }


@pytest.mark.parametrize("kind", ["ros1", "rosbag2-sqlite3", "rosbag2-mcap"])
def test_counts_spans_and_offsets_are_what_rosbags_reads(
    bags: dict[str, Path], shared_data: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    path = shared_data / "stereo-image-proc" / "sip_kitti.bag" if kind == "ros1" else bags[kind]
    document = info_json(capsys, path)["bags"][0]
    expected = rosbags_facts(path)
    assert shown(document) == expected
    assert document["format"] == kind
    assert document["messages"] == sum(entry[1] for entry in expected.values())
    first = min(entry[2] for entry in expected.values())
    last = max(entry[3] for entry in expected.values())
    assert document["log_time"] == {
        "first_ns": first,
        "last_ns": last,
        "duration_s": (last - first) / 1e9,
    }


def test_a_plain_mcap_file_shows_what_the_same_rosbag2_bag_shows(
    bags: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    plain, folder = (info_json(capsys, bags[k])["bags"][0] for k in ("mcap", "rosbag2-mcap"))
    assert plain["format"] == "mcap"
    assert plain["topics"] == folder["topics"]
    assert plain["log_time"] == folder["log_time"]


def test_the_recorded_stamp_offset_of_stereo_image_proc_is_shown(
    shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = shared_data / "stereo-image-proc" / "sip_kitti.bag"
    capsys.readouterr()
    assert main(["info", str(path)]) == 0
    text = capsys.readouterr().out
    assert "header stamps are 6.2 years (1.96e+08 s) before the log time" in text
    assert "/stereo_bm/disparity" in text
    assert "1.962e+08" in text


@pytest.mark.parametrize("kind", ["ros1", "rosbag2-sqlite3", "mcap"])
def test_the_suggested_command_runs_and_scores_every_method(
    bags: dict[str, Path],
    shared_data: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    kind: str,
) -> None:
    path = shared_data / "stereo-image-proc" / "sip_kitti.bag" if kind == "ros1" else bags[kind]
    document = info_json(capsys, path)["bags"][0]
    words = shlex.split(document["command"])
    assert words[:3] == ["dispeval", "bag", str(path)]
    methods = [t["name"] for t in document["topics"] if t["use"] == "--method"]
    assert words.count("--method") == len(methods) > 1
    assert "--camera-info" in words
    if kind != "ros1":
        assert words[words.index("--gt") + 1] == GT_TOPIC
    assert main([*words[1:], "--out", str(tmp_path / "out"), "--quiet", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    scored = summary["sequences"][0]["counts"]
    named = [words[i + 1].split("=")[0] for i, word in enumerate(words) if word == "--method"]
    assert sorted(scored) == sorted(named)
    assert all(counts["matched"] > 0 for counts in scored.values())


def test_several_bags_of_the_same_topics_get_one_command(
    bags: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    document = info_json(capsys, bags["rosbag2-sqlite3"], bags["mcap"])
    words = shlex.split(document["command"])
    assert words[2:4] == [str(bags["rosbag2-sqlite3"]), str(bags["mcap"])]
    assert words[4:] == shlex.split(document["bags"][0]["command"])[3:]


def test_an_unreadable_bag_is_one_line_and_the_others_are_still_shown(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x01" * 64)
    capsys.readouterr()
    code = main(["info", str(junk), str(bags["mcap"])])
    captured = capsys.readouterr()
    assert_refused(code, captured.err, "dispeval info: error:", str(junk))
    assert f"{bags['mcap']}: mcap" in captured.out
    assert "suggested: dispeval bag" in captured.out


def test_a_cut_recording_is_described_up_to_the_damage(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    complete = tmp_path / "drive.mcap"  # several chunks: the cut falls in a later one
    write_bag(complete, synthetic_frames(6, 320, 96, 10.0, seed=5), storage="mcap")
    data = complete.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    document = info_json(capsys, cut)["bags"][0]
    assert "truncated" in document["damage"]
    whole = {t["name"]: t for t in info_json(capsys, complete)["bags"][0]["topics"]}
    assert document["messages"] < sum(t["count"] for t in whole.values())
    for topic in document["topics"]:
        assert 0 < topic["count"] <= whole[topic["name"]]["count"]
        assert topic["first_log_ns"] == whole[topic["name"]]["first_log_ns"]
        assert topic["last_log_ns"] <= whole[topic["name"]]["last_log_ns"]
        assert topic["last_log_ns"] <= document["log_time"]["last_ns"]


def test_method_names_are_short_and_unique() -> None:
    assert method_names(["/stereo/sgbm/disparity", "/stereo_bm/disparity"]) == [
        "sgbm",
        "stereo_bm",
    ]
    assert method_names(["/a/sgbm/disparity", "/b/sgbm/disparity"]) == [
        "a_sgbm_disparity",
        "b_sgbm_disparity",
    ]


@pytest.mark.slow
def test_a_kitti_raw_drive_gets_the_tolerance_its_scan_stamps_need(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = tmp_path / "drive"
    assert main(["make-bag", str(bag), "--scene", str(shared_data / KITTI_RAW)]) == 0
    document = info_json(capsys, bag)["bags"][0]
    words = shlex.split(document["command"])
    assert words[words.index("--gt-cloud") + 1] == "/lidar/points"
    assert words[words.index("--tolerance") + 1] == "11"  # scans 10.48–10.55 ms from the images
    assert any("up to 10.55 ms" in note for note in document["notes"])
    assert main([*words[1:], "--out", str(tmp_path / "out"), "--quiet", "--json"]) == 0
    counts = json.loads(capsys.readouterr().out)["sequences"][0]["counts"]
    assert len(counts) == 5
    matched = {"matched": 11, "unmatched": 0, "dropped": 0, "failed": 0}
    assert all(c == matched for c in counts.values())
    without = [*words[1 : words.index("--tolerance")], "--out", str(tmp_path / "o2"), "--quiet"]
    assert main([*without, "--json"]) == 0  # the default tolerance joins nothing
    counts = json.loads(capsys.readouterr().out)["sequences"][0]["counts"]
    assert all(c["matched"] == 0 for c in counts.values())
