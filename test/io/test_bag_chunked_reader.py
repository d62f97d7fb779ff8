"""The chunked MCAP reader gives exactly what the library readers give, or lets them take over.

Every message of every bag in the repository and of synthetic bags in every storage written
(compressed and not; big-endian, padded and odd-step images; several messages at one log time)
is compared field by field with rosbags' (or mcap_ros2's) deserialisation of the library
reader's bytes; damaged chunks and undecodable messages give the library path's one-line error.
"""

from __future__ import annotations

import dataclasses
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from dispeval_ros.core.camera import Camera
from dispeval_ros.errors import InputError
from dispeval_ros.io.bags import BagSource, BagWriter, chunked_mcap, mcap_reader, rosbags_reader
from dispeval_ros.io.bags.chunked_mcap import NotChunked, fast_then_slow
from dispeval_ros.io.encoders import camera_info_to_msg, disparity_to_msg, image_to_msg

HUMBLE = get_typestore(Stores.ROS2_HUMBLE)
REPO_BAGS = sorted(
    p for p in (Path(__file__).resolve().parents[2] / "bags").iterdir() if p.is_dir()
)
T0 = 1_700_000_000_000_000_000
STEP = 100_000_000


@pytest.fixture
def library_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """BagSource without the chunked reader: the library readers alone."""
    monkeypatch.setattr(rosbags_reader, "open_chunked", lambda *_: None)
    monkeypatch.setattr(mcap_reader, "open_chunked", lambda *_: None)


def read_all(path: Path, start: int | None = None, stop: int | None = None) -> list[Any]:
    with BagSource(path) as source:
        return list(source.messages(list(source.topics), start, stop))


def uses_chunked(path: Path) -> bool:
    with BagSource(path) as source:
        return source._backend.chunked is not None


def assert_same_message(a: Any, b: Any, where: str = "msg") -> None:
    """Field by field: same types, same values, arrays of the same dtype, shape and bytes."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        assert isinstance(a, np.ndarray), where
        assert isinstance(b, np.ndarray), where
        assert (a.dtype, a.shape) == (b.dtype, b.shape), where
        assert a.tobytes() == b.tobytes(), where
        return
    assert type(a).__qualname__ == type(b).__qualname__, where  # each reader has its types
    if dataclasses.is_dataclass(a):
        for field in dataclasses.fields(a):
            assert_same_message(getattr(a, field.name), getattr(b, field.name), field.name)
    elif hasattr(a, "__slots__") and not isinstance(a, (str, bytes)):  # mcap_ros2 objects
        for name in a.__slots__:
            assert_same_message(getattr(a, name), getattr(b, name), f"{where}.{name}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for index, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same_message(x, y, f"{where}[{index}]")
    else:
        assert a == b or (a != a and b != b), where  # NaN equals NaN here


def assert_same_stream(ours: list[Any], theirs: list[Any]) -> None:
    assert [(topic, log) for topic, log, _ in ours] == [(t, log) for t, log, _ in theirs]
    for (topic, log, a), (_, _, b) in zip(ours, theirs, strict=True):
        assert_same_message(a, b, f"{topic} at {log}")


def library_stream(path: Path, monkeypatch: pytest.MonkeyPatch, *window: int | None) -> list:
    with monkeypatch.context() as patch:
        patch.setattr(rosbags_reader, "open_chunked", lambda *_: None)
        patch.setattr(mcap_reader, "open_chunked", lambda *_: None)
        return read_all(path, *window)


# -- every bag of the repository -------------------------------------------------------------


@pytest.mark.parametrize("bag", REPO_BAGS, ids=[p.name for p in REPO_BAGS])
def test_repository_bags_equal_rosbags_deserialisation(bag: Path) -> None:
    from rosbags.highlevel import AnyReader

    if any(bag.glob("*.mcap")):
        assert uses_chunked(bag)
    ours = read_all(bag)
    with AnyReader([bag]) as reader:
        theirs = [
            (c.topic, log, reader.deserialize(raw, c.msgtype))
            for c, log, raw in reader.messages(reader.connections)
        ]
    assert len(ours) == len(theirs) > 0
    assert_same_stream(ours, theirs)


# -- synthetic bags in every storage ---------------------------------------------------------


def images(index: int) -> Iterator[tuple[str, Any]]:
    """Images and disparities in every layout the decoders meet, at one frame."""
    rng = np.random.default_rng(index)
    stamp = T0 + index * STEP
    disparity = rng.uniform(0.5, 100, (5, 7)).astype(np.float32)
    disparity[0, 0] = np.nan
    yield "/disp", disparity_to_msg(HUMBLE, disparity, stamp, "cam", 700.0, 0.5, 0.0, 127.0)
    gt = rng.uniform(1, 50, (5, 7)).astype(np.float32)
    plain = image_to_msg(HUMBLE, gt, stamp, "cam", "32FC1")
    yield "/gt", plain
    big = gt.astype(">f4").view(np.uint8).reshape(5, -1)
    padded = np.full((5, big.shape[1] + 3), 0xAB, np.uint8)  # odd step: 31 bytes a row
    padded[:, : big.shape[1]] = big
    yield (
        "/gt_big_odd",
        dataclasses.replace(plain, data=padded.reshape(-1), step=31, is_bigendian=1),
    )
    depth = rng.integers(0, 65535, (4, 3), dtype=np.uint16)
    yield "/depth16", image_to_msg(HUMBLE, depth, stamp, "frame_" + "x" * index, "16UC1")
    colour = rng.integers(0, 255, (3, 5, 3), dtype=np.uint8)
    yield "/rgb", image_to_msg(HUMBLE, colour, stamp, "", "rgb8")
    camera = Camera(700.0 + index, 0.5)
    yield "/left/info", camera_info_to_msg(HUMBLE, camera, 7, 5, stamp, "cam", False)
    yield "/right/info", camera_info_to_msg(HUMBLE, camera, 7, 5, stamp, "cam", True, 3.25)


TYPES = {
    "/disp": "stereo_msgs/msg/DisparityImage",
    "/gt": "sensor_msgs/msg/Image",
    "/gt_big_odd": "sensor_msgs/msg/Image",
    "/depth16": "sensor_msgs/msg/Image",
    "/rgb": "sensor_msgs/msg/Image",
    "/left/info": "sensor_msgs/msg/CameraInfo",
    "/right/info": "sensor_msgs/msg/CameraInfo",
}
FORMATS = ["rosbag2-sqlite3", "rosbag2-mcap", "mcap"]


def write_synthetic(
    path: Path, fmt: str, compress: bool, frames: int = 6, filler: bool = False
) -> Path:
    """Frames whose messages share a log time per frame (ties), some written out of order.

    ``filler``: a 0.6 MB image per frame too, so that MCAP chunks (1 MB) hold a frame or two.
    """
    with BagWriter(path, fmt, compress=compress) as writer:
        for topic, msgtype in TYPES.items():
            writer.add_topic(topic, msgtype)
        if filler:
            writer.add_topic("/filler", "sensor_msgs/msg/Image")
        for index in [*range(frames - 2), frames - 1, frames - 2]:  # the last two swapped
            for topic, msg in images(index):
                writer.write(topic, T0 + index * STEP, msg)
            if filler:
                big = np.full((600, 1000), index, np.uint8)
                writer.write(
                    "/filler", T0 + index * STEP, image_to_msg(HUMBLE, big, 0, "", "mono8")
                )
    return path


@pytest.fixture(scope="module", params=[(f, c) for f in FORMATS for c in (False, True)])
def synthetic(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    fmt, compress = request.param
    root = tmp_path_factory.mktemp(f"{fmt}-{compress}")
    return write_synthetic(root / ("bag.mcap" if fmt == "mcap" else "bag"), fmt, compress)


def test_synthetic_bags_equal_the_library_readers(
    synthetic: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with BagSource(synthetic) as source:
        mcap = source.format in ("mcap", "rosbag2-mcap")
    assert uses_chunked(synthetic) == mcap
    ours = read_all(synthetic)
    assert len(ours) == 6 * len(TYPES)
    assert_same_stream(ours, library_stream(synthetic, monkeypatch))
    for window in [(T0 + STEP, T0 + 4 * STEP), (None, T0 + 2 * STEP + 1), (T0 + 5 * STEP, None)]:
        assert_same_stream(
            read_all(synthetic, *window), library_stream(synthetic, monkeypatch, *window)
        )


def test_synthetic_bags_equal_the_libraries_own_deserialisation(synthetic: Path) -> None:
    """rosbags' AnyReader for rosbag2 bags, mcap with mcap_ros2 for plain MCAP files."""
    if synthetic.suffix == ".mcap":
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory

        with synthetic.open("rb") as file:
            reader = make_reader(file, decoder_factories=[DecoderFactory()])
            theirs = [
                (channel.topic, message.log_time, decoded)
                for _, channel, message, decoded in reader.iter_decoded_messages()
            ]
    else:
        from rosbags.highlevel import AnyReader

        with AnyReader([synthetic]) as reader:
            theirs = [
                (c.topic, log, reader.deserialize(raw, c.msgtype))
                for c, log, raw in reader.messages(reader.connections)
            ]
    assert_same_stream(read_all(synthetic), theirs)


# -- damage ---------------------------------------------------------------------------------


def storage_file(path: Path) -> Path:
    return path if path.is_file() else next(path.glob("*.mcap"))


def with_chunk_crcs_refreshed(path: Path, data: bytearray) -> bytes:
    """``data`` (an uncompressed MCAP file changed in place) with every chunk's CRC recomputed."""
    summary = chunked_mcap.mcap_summary(path)
    for index in summary.chunk_indexes:
        head = index.chunk_start_offset + 9  # opcode, length
        size = int.from_bytes(data[head + 16 : head + 24], "little")
        name = int.from_bytes(data[head + 28 : head + 32], "little")
        records = head + 32 + name + 8
        crc = zlib.crc32(data[records : records + size])
        data[head + 24 : head + 28] = crc.to_bytes(4, "little")
    return bytes(data)


def error_of(path: Path) -> tuple[str, int]:
    """The error reading every message raises, and how many messages came before it."""
    got = 0
    with BagSource(path) as source:
        try:
            for _ in source.messages(list(source.topics)):
                got += 1
        except InputError as error:
            text = str(error)
        else:
            raise AssertionError(f"{path} was read without an error")
    assert "\n" not in text
    return text, got


@pytest.mark.parametrize("fmt", ["rosbag2-mcap", "mcap"])
def test_an_undecodable_message_is_the_library_paths_error(
    fmt: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = write_synthetic(tmp_path / ("bag.mcap" if fmt == "mcap" else "bag"), fmt, False, 6, True)
    file = storage_file(path)
    data = bytearray(file.read_bytes())
    at = data.index(b"rgb8\x00", len(data) // 2)  # the encoding string of a later /rgb
    data[at - 4 : at] = (0x7FFFFFF0).to_bytes(4, "little")  # its length: far past the end
    file.write_bytes(with_chunk_crcs_refreshed(file, data))
    assert uses_chunked(path)
    ours = error_of(path)
    assert "cannot deserialize the message on /rgb" in ours[0]
    assert ours[1] > 0
    with monkeypatch.context() as patch:
        patch.setattr(rosbags_reader, "open_chunked", lambda *_: None)
        patch.setattr(mcap_reader, "open_chunked", lambda *_: None)
        assert error_of(path) == ours


def test_a_damaged_chunk_lets_the_library_reader_report_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = write_synthetic(tmp_path / "bag.mcap", "mcap", False, 6, True)  # with chunk CRCs
    data = bytearray(path.read_bytes())
    at = data.index(b"rgb8\x00", len(data) // 2)
    data[at] ^= 0xFF  # still decodable, but the chunk's CRC no longer matches
    path.write_bytes(bytes(data))
    ours = error_of(path)
    assert "damaged" in ours[0]
    assert 0 < ours[1] < 6 * len(TYPES)
    with monkeypatch.context() as patch:
        patch.setattr(mcap_reader, "open_chunked", lambda *_: None)
        assert error_of(path) == ours


def test_fast_then_slow_takes_over_after_the_items_yielded() -> None:
    def fast() -> Iterator[int]:
        yield 0
        yield 1
        raise NotChunked("chunk 2")

    assert list(fast_then_slow(fast(), lambda: iter(range(5)))) == [0, 1, 2, 3, 4]
    assert list(fast_then_slow(iter(range(3)), lambda: iter(()))) == [0, 1, 2]


def test_what_the_chunked_reader_does_not_know_is_left_to_the_libraries(tmp_path: Path) -> None:
    path = write_synthetic(tmp_path / "bag.mcap", "mcap", False)
    summary = chunked_mcap.mcap_summary(path)
    assert chunked_mcap.open_chunked(path, summary) is not None
    first = summary.chunk_indexes[0]
    summary.chunk_indexes[0] = dataclasses.replace(first, chunk_length=path.stat().st_size)
    assert chunked_mcap.open_chunked(path, summary) is None
    # Chunks without message indexes: rosbags skips them, mcap reads them; neither is guessed.
    summary.chunk_indexes[0] = dataclasses.replace(first, message_index_offsets={})
    assert chunked_mcap.open_chunked(path, summary) is None
    summary.chunk_indexes[0] = dataclasses.replace(first, compression="bz2")
    assert chunked_mcap.open_chunked(path, summary) is None


# -- provenance digests ----------------------------------------------------------------------


def test_stream_digests_are_the_same_from_the_map(
    synthetic: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from dispeval_ros.io.bags.source import BagSource as Source
    from dispeval_ros.io.provenance import stream_digests

    topics = list(TYPES)
    with BagSource(synthetic) as source:
        mapped = source.serialized_messages(topics) is not None
        assert mapped == (source.format in ("mcap", "rosbag2-mcap"))
    ours = stream_digests(synthetic, topics)
    monkeypatch.setattr(Source, "serialized_messages", lambda *_: None)
    assert stream_digests(synthetic, topics) == ours
    assert all(entry["messages"] == 6 for entry in ours.values())


def test_stream_digests_continue_with_the_library_after_a_chunk_it_cannot_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from dispeval_ros.io.bags.source import BagSource as Source
    from dispeval_ros.io.provenance import stream_digests

    path = write_synthetic(tmp_path / "bag", "rosbag2-mcap", False, 6, True)
    topics = [*TYPES, "/filler"]
    expected = stream_digests(path, topics)
    last = chunked_mcap.mcap_summary(storage_file(path)).chunk_indexes[-1]
    original = chunked_mcap.ChunkedMcap._checked_records

    def refuse_the_last(self: Any, chunk: Any) -> memoryview:
        if chunk.offset == last.chunk_start_offset:
            raise NotChunked("not this one")
        return original(self, chunk)

    monkeypatch.setattr(chunked_mcap.ChunkedMcap, "_checked_records", refuse_the_last)
    with BagSource(path) as source:
        assert source.serialized_messages(topics) is not None
    assert stream_digests(path, topics) == expected
    monkeypatch.setattr(Source, "serialized_messages", lambda *_: None)
    assert stream_digests(path, topics) == expected


def test_messages_compressed_by_rosbag2_are_left_to_rosbags(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """rosbag2's per-message compression: the storage holds zstd frames, not CDR."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    path = tmp_path / "bag"
    writer = Writer(path, version=8, storage_plugin=StoragePlugin.MCAP)
    writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    with writer:
        connections = {
            topic: writer.add_connection(topic, msgtype, typestore=HUMBLE)
            for topic, msgtype in TYPES.items()
        }
        for index in range(3):
            for topic, msg in images(index):
                raw = HUMBLE.serialize_cdr(msg, TYPES[topic])
                writer.write(connections[topic], T0 + index * STEP, raw)
    assert not uses_chunked(path)
    ours = read_all(path)
    assert len(ours) == 3 * len(TYPES)
    assert_same_stream(ours, library_stream(path, monkeypatch))
