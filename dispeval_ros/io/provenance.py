"""Digests of the inputs a result was made from: files (sha256), bag message streams per topic.

A stream's digest is the hash of its messages as read from the bag, in log-time order: for
each message, its log time (8 bytes, little-endian), the length of its serialized bytes (8
bytes, little-endian) and those bytes (CDR for ROS 2 bags and MCAP, ROS 1 serialization for
ROS 1 bags). The same recording gives the same digest in any storage of the same
serialization, and a changed, dropped or reordered message changes it.

The hash is :data:`STREAM_DIGEST` (BLAKE3: ~4× sha256's speed, as collision-resistant), or
sha256 where the ``blake3`` package is missing. Each topic's entry is keyed by the name of the
algorithm that made it (``{"blake3": hex, "messages": n}``; results made before BLAKE3 hold
``{"sha256": hex, …}``), so a record always says how to re-make it, and two entries of
different algorithms are never compared as if they were one (:func:`same_stream`).
"""

from __future__ import annotations

import hashlib
import struct
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

from dispeval_ros.errors import InputError
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.bags.chunked_mcap import fast_then_slow


class Hasher(Protocol):
    """What a stream digest needs of a hash object (hashlib's and blake3's have it)."""

    def update(self, data: bytes | memoryview, /) -> object:
        """Hash ``data`` after what came before."""

    def hexdigest(self) -> str:
        """The digest of everything hashed so far, in hex."""


STREAM_DIGEST = "blake3"
"""The algorithm of new stream digests (the key of each topic's entry names the one used)."""

FALLBACK_DIGEST = "sha256"
"""The algorithm used instead where ``blake3`` is not installed (a ROS build without pip:
blake3 has no rosdep key), recorded as such."""

HASHERS: dict[str, Callable[[], Hasher]] = {FALLBACK_DIGEST: hashlib.sha256}
"""Algorithm name → a new hash object: every algorithm a stream entry may be keyed by."""
try:
    from blake3 import blake3 as _blake3
except ImportError:  # pragma: no cover - blake3 is a pip requirement
    pass
else:
    HASHERS[STREAM_DIGEST] = _blake3


def stream_algorithm() -> str:
    """The algorithm new stream digests are made with: :data:`STREAM_DIGEST` where installed."""
    return STREAM_DIGEST if STREAM_DIGEST in HASHERS else FALLBACK_DIGEST


def entry_digest(entry: Mapping[str, object]) -> tuple[str, str]:
    """``(algorithm, hex)`` of one topic's entry, whichever algorithm made it."""
    found = [(name, str(entry[name])) for name in (STREAM_DIGEST, FALLBACK_DIGEST) if name in entry]
    if len(found) != 1:
        raise ValueError(
            f"a stream digest names one of {STREAM_DIGEST}, {FALLBACK_DIGEST}: {entry}"
        )
    return found[0]


def same_stream(a: Mapping[str, object], b: Mapping[str, object]) -> bool | None:
    """Whether two topic entries digest the same messages; None when their algorithms differ.

    None is not "different": the two cannot be told apart without re-hashing one stream with
    the other's algorithm (:func:`verify_streams`).
    """
    (algorithm_a, hex_a), (algorithm_b, hex_b) = entry_digest(a), entry_digest(b)
    if algorithm_a != algorithm_b:
        return None
    return hex_a == hex_b and a.get("messages") == b.get("messages")


_CHUNK = 1 << 20


def file_sha256(path: Path) -> str:
    """sha256 of a file's bytes (hex), or a one-line error naming the file."""
    digest = hashlib.sha256()
    try:
        with Path(path).open("rb") as file:
            for block in iter(lambda: file.read(_CHUNK), b""):
                digest.update(block)
    except OSError as error:
        raise InputError(
            f"{path}: cannot read for its sha256 ({error.strerror or error})"
        ) from None
    return digest.hexdigest()


def files_sha256(paths: Iterable[Path]) -> dict[str, str]:
    """Path → sha256 of each distinct file."""
    return {str(path): file_sha256(path) for path in dict.fromkeys(paths)}


def _raw_rosbags(paths: list[Path], topics: Sequence[str]) -> Iterator[tuple[str, int, bytes]]:
    from rosbags.highlevel import AnyReader

    with AnyReader(paths) as reader:
        connections = [c for c in reader.connections if c.topic in topics]
        for connection, log_ns, raw in reader.messages(connections):
            yield connection.topic, int(log_ns), bytes(raw)


def _raw_mcap(path: Path, topics: Sequence[str]) -> Iterator[tuple[str, int, bytes]]:
    from mcap.reader import make_reader

    with path.open("rb") as stream:
        reader = make_reader(stream)
        try:
            indexed = reader.get_summary() is not None
        except Exception:  # no footer or summary: a recording killed mid-write
            indexed = False
        if not indexed:
            yield from _scanned_mcap(path, topics)
            return
        for _schema, channel, message in reader.iter_messages(
            topics=list(topics), log_time_order=True
        ):
            yield channel.topic, int(message.log_time), bytes(message.data)


def _scanned_mcap(path: Path, topics: Sequence[str]) -> Iterator[tuple[str, int, bytes]]:
    """An MCAP without summary, read from its start in file order as the evaluation reads it.

    Up to any damage, then the evaluation's own ``InputError``: the digests stop where it did.
    """
    from mcap.records import Channel, Message

    from dispeval_ros.io.bags.mcap_reader import damage_text, scan_records

    wanted = set(topics)
    channels: dict[int, str] = {}
    count, last = 0, -1
    with path.open("rb") as stream:
        try:
            for record in scan_records(stream):
                if isinstance(record, Channel):
                    channels[record.id] = record.topic
                elif isinstance(record, Message):
                    count += 1
                    last = max(last, record.log_time)
                    topic = channels.get(record.channel_id)
                    if topic in wanted:
                        yield topic, int(record.log_time), bytes(record.data)
        except Exception as error:
            raise InputError(damage_text(path, error, count, last)) from None


def _raw_messages(path: Path, fmt: str, topics: Sequence[str]) -> Iterator[tuple[str, int, bytes]]:
    if fmt == "mcap":
        return _raw_mcap(path, topics)
    if fmt == "rosbag2-mcap":
        folder = path if path.is_dir() else path.parent
        files = sorted(folder.glob("*.mcap"))
        if len(files) == 1:
            return _raw_mcap(files[0], topics)
    if path.is_dir() and fmt == "ros1":
        return _raw_rosbags(sorted(path.glob("*.bag")), topics)
    return _raw_rosbags([path], topics)


def stream_digests(
    bag: Path,
    topics: Sequence[str],
    source: BagSource | None = None,
    algorithm: str | None = None,
) -> dict[str, dict[str, object]]:
    """Per topic of ``bag``: ``{algorithm: hex, "messages": count}`` of its serialized messages.

    ``source``: the bag already open (its format and topics are taken from it, and the
    messages read with a reader of their own). ``algorithm``: a key of :data:`HASHERS`
    (default :func:`stream_algorithm`). A bag damaged on the way is an error; see
    :func:`digests_to_damage` to hash what precedes the damage.
    """
    digests, damage = digests_to_damage(bag, topics, source, algorithm)
    if damage is not None:
        raise InputError(damage)
    return digests


def digests_to_damage(
    bag: Path,
    topics: Sequence[str],
    source: BagSource | None = None,
    algorithm: str | None = None,
) -> tuple[dict[str, dict[str, object]], str | None]:
    """:func:`stream_digests` of the messages before any damage, and what the damage is.

    A recording killed mid-write is evaluated up to its damage; its provenance then proves
    exactly the messages that were scored, and says where reading stopped (None: nowhere).
    """
    if source is None:
        with BagSource(bag) as opened:
            return digests_to_damage(bag, topics, opened, algorithm)
    algorithm = algorithm or stream_algorithm()
    if algorithm not in HASHERS:  # a BLAKE3 record re-checked where blake3 is not installed
        raise InputError(
            f"{bag}: its digests are {algorithm}, which needs the {algorithm} package "
            f"(pip install {algorithm}); this installation hashes with {', '.join(HASHERS)}"
        )
    fmt = source.format
    wanted = [t for t in dict.fromkeys(topics) if t in source.topics]
    digests = {topic: HASHERS[algorithm]() for topic in wanted}
    counts = dict.fromkeys(wanted, 0)

    def library() -> Iterator[tuple[str, int, bytes | memoryview]]:
        return _raw_messages(Path(bag), fmt, wanted)

    mapped = source.serialized_messages(wanted)  # the same bytes, in the same order, no copy
    stream = library() if mapped is None else fast_then_slow(mapped, library)
    damage: str | None = None
    try:
        for topic, log_ns, raw in stream:
            digest = digests[topic]
            digest.update(struct.pack("<qQ", log_ns, len(raw)))
            digest.update(raw)
            counts[topic] += 1
    except InputError as error:
        damage = str(error)
    except Exception as error:
        damage = f"{bag}: cannot read the messages for their {algorithm} ({error})"
    hashed = {t: {algorithm: digests[t].hexdigest(), "messages": counts[t]} for t in wanted}
    return hashed, damage


def verify_streams(bag: Path, record: Mapping[str, Any]) -> dict[str, bool]:
    """Topic → whether ``bag`` still holds the messages a stored stream record digests.

    ``record``: one sequence's entry of a provenance's ``inputs.streams`` (its ``topics``, and
    ``read_up_to`` for a bag read up to damage). Each topic is re-hashed with the algorithm its
    entry names, so records made with sha256 verify as they did.
    """
    topics: Mapping[str, Mapping[str, object]] = record["topics"]
    by_algorithm: dict[str, list[str]] = {}
    for topic, entry in topics.items():
        by_algorithm.setdefault(entry_digest(entry)[0], []).append(topic)
    verdict: dict[str, bool] = {}
    with BagSource(bag) as source:
        for algorithm, names in by_algorithm.items():
            now, damage = digests_to_damage(bag, names, source, algorithm)
            stopped = damage is not None  # as the stored run did, or not
            for topic in names:
                agrees = now.get(topic) is not None and same_stream(topics[topic], now[topic])
                verdict[topic] = bool(agrees) and stopped == ("read_up_to" in record)
    return verdict
