"""A recording killed mid-write (MCAP without summary, a truncated record) finishes.

The evaluation reads up to the damage; the provenance then hashes exactly the messages before
it and says where reading stopped, so neither the run nor ``--resume`` fails on the digest.
"""

from __future__ import annotations

import hashlib
import json
import struct
from pathlib import Path

import blake3
import pytest
from bag_support import METHODS, bag_args
from mcap.reader import make_reader

from dispeval_ros.cli.main import main
from dispeval_ros.io.provenance import verify_streams
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import disparity_topic, synthetic_frames, write_bag


def killed_copy(bag: Path, share: float) -> Path:
    """The first ``share`` of the file's bytes: no footer, no summary, a record cut short."""
    data = bag.read_bytes()
    out = bag.with_name("killed.mcap")
    out.write_bytes(data[: int(len(data) * share)])
    return out


HASHES = {"blake3": blake3.blake3, "sha256": hashlib.sha256}


def digests_before(
    bag: Path, topics: list[str], count: int, algorithm: str = "blake3"
) -> dict[str, dict[str, object]]:
    """The digest definition over the first ``count`` messages of the intact file (file order)."""
    digests = {topic: HASHES[algorithm]() for topic in topics}
    counts = dict.fromkeys(topics, 0)
    with bag.open("rb") as stream:
        for index, (_, channel, message) in enumerate(make_reader(stream).iter_messages()):
            if index >= count:
                break
            if channel.topic in digests:
                digests[channel.topic].update(
                    struct.pack("<qQ", message.log_time, len(message.data))
                )
                digests[channel.topic].update(message.data)
                counts[channel.topic] += 1
    return {t: {algorithm: digests[t].hexdigest(), "messages": counts[t]} for t in topics}


@pytest.fixture(scope="module")
def killed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("killed")
    intact = folder / "drive.mcap"
    write_bag(intact, synthetic_frames(24, 320, 160, 10.0, seed=3), storage="mcap")
    return intact, killed_copy(intact, 0.55)


def test_a_killed_recording_finishes_and_resumes(killed: tuple[Path, Path], tmp_path: Path) -> None:
    intact, bag = killed
    out = tmp_path / "out"
    assert main(bag_args(bag, out)) == 0
    with ResultsStore.open(out) as store:
        (sequence,) = store.sequences()
        frames = len(store.stamps(sequence))
        assert 0 < frames < 24
        scored = store.match_counts(sequence)
        assert set(scored) == set(METHODS)
        (problem,) = store.problems(sequence)
        assert problem.message.startswith("reading stopped:")
        assert "truncated" in problem.message
    streams = json.loads((out / "summary.json").read_text())["provenance"]["inputs"]["streams"]
    record = streams[sequence]
    # the digests stopped where the evaluation did, and say it in the same words
    assert record["read_up_to"] == problem.message.removeprefix("reading stopped: ")
    assert "MCAP file is truncated (it ends before its footer) after" in record["read_up_to"]
    read = int(record["read_up_to"].split("after ")[1].split(" messages")[0])
    topics = list(record["topics"])
    assert record["topics"] == digests_before(intact, topics, read)
    assert all(verify_streams(bag, record).values())  # it re-reads to the same damage
    before = {**record, "topics": digests_before(intact, topics, read, "sha256")}
    assert all(verify_streams(bag, before).values())  # as a record made with sha256 does
    assert not any(verify_streams(intact, record).values())  # the whole file: more messages
    for method, found in scored.items():  # every scored estimate is among the hashed messages
        assert record["topics"][disparity_topic(method)]["messages"] >= found.matched, method
    assert main(bag_args(bag, out, "--resume")) == 0
    with ResultsStore.open(out) as store:
        assert len(store.stamps(sequence)) == frames
