"""Publish a bag's topics on DDS with their types and recorded timing, as ``ros2 bag play`` does.

Payloads:

- rosbag2 bags (sqlite3 or MCAP storage) are read with rosbags' ``AnyReader`` and their recorded
  CDR bytes are published as they are: nothing is deserialised. Types (and type hashes) come
  from the bag's own message definitions, so any message type plays.
- ROS 1 bags, plain MCAP files and rosbag2 bags rosbags cannot open (a cut-off recording) are
  read with :class:`~dispeval_ros.io.bags.BagSource`; each message is converted field by field
  (by name, case-insensitively: ROS 1's ``T``, ``P`` and ``K`` become ``t``, ``p``, ``k``, a
  header's ``seq`` is dropped) into the ROS 2 Humble type of the same name and serialised with
  rosbags. Types that are not Humble's cannot be played from these formats.

Timing: each message goes out at ``first + (log time − first log time) / rate`` on the
monotonic clock (``rate`` None: as fast as possible); ``loop`` plays again from the start with
the same header stamps, as ``ros2 bag play --loop`` does. Writers are reliable, keep-last 10,
volatile (``ros2 bag play``'s default), which matches reliable and best-effort subscribers.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dispeval_ros.dds.transport import DdsTransport, RawWriter, humble_typestore
from dispeval_ros.dds.wire import (
    PLAYBACK,
    STATIC_TF,
    STATIC_TF_TOPIC,
    QosProfile,
    normal_msgtype,
    ros_topic_name,
)
from dispeval_ros.errors import ConfigurationError, DispevalError, InputError
from dispeval_ros.io.bags import BagSource, TopicInfo
from dispeval_ros.io.bags.common import missing_topic

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

RAW_FORMATS = ("rosbag2-sqlite3", "rosbag2-mcap")
_DTYPES = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


@dataclass(frozen=True)
class PlayedTopic:
    """A topic being played: its ROS 2 type and the typestore that describes it."""

    name: str
    msgtype: str
    typestore: Any
    count: int


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split()) or type(error).__name__
    return text if len(text) <= 300 else text[:297] + "..."


class _RawSource:
    """Recorded CDR payloads of a rosbag2 bag, in log-time order (rosbags, no decoding)."""

    def __init__(self, path: Path) -> None:
        from rosbags.highlevel import AnyReader

        folder = path if path.is_dir() else path.parent
        paths = [folder] if (folder / "metadata.yaml").is_file() else [path]
        self.reader = AnyReader(paths, default_typestore=humble_typestore())
        self.reader.open()
        self.typestore = self.reader.typestore

    def msgtype(self, topic: str) -> str:
        types = {normal_msgtype(c.msgtype) for c in self.reader.connections if c.topic == topic}
        if len(types) != 1:
            raise InputError(
                f"topic {topic} has several message types ({', '.join(sorted(types))})"
            )
        return types.pop()

    def messages(self, topics: Sequence[str]) -> Iterator[tuple[str, int, Any]]:
        connections = [c for c in self.reader.connections if c.topic in topics]
        for connection, log_ns, raw in self.reader.messages(connections):
            yield connection.topic, int(log_ns), raw

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.reader.close()


class _DecodedSource:
    """Messages of any bag :class:`BagSource` reads, converted to ROS 2 Humble and serialised."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.source = BagSource(path)
        self.typestore = humble_typestore()

    def msgtype(self, topic: str) -> str:
        msgtype = normal_msgtype(self.source.topics[topic].msgtype)
        if msgtype not in self.typestore.types:
            raise InputError(
                f"{self.path}: topic {topic} has type {msgtype}, which is not a ROS 2 Humble type;"
                f" only rosbag2 bags play their own types ({self.source.format} bag here)"
            )
        return msgtype

    def messages(self, topics: Sequence[str]) -> Iterator[tuple[str, int, Any]]:
        types = {topic: self.msgtype(topic) for topic in topics}
        for topic, log_ns, msg in self.source.messages(list(topics)):
            try:
                converted = to_ros2(self.typestore, types[topic], msg)
                payload = self.typestore.serialize_cdr(converted, types[topic])
            except DispevalError:
                raise
            except Exception as error:
                raise InputError(
                    f"{self.path}: cannot convert the message on {topic} at log time {log_ns} ns"
                    f" to {types[topic]} ({_one_line(error)})"
                ) from None
            yield topic, log_ns, payload

    def close(self) -> None:
        self.source.close()


def _attribute(obj: Any, name: str) -> Any:
    for candidate in (name, name.upper()):
        if hasattr(obj, candidate):
            return getattr(obj, candidate)
    lower = name.lower()
    for candidate in dir(obj):
        if candidate.lower() == lower and not candidate.startswith("_"):
            return getattr(obj, candidate)
    raise ValueError(f"the message has no field '{name}'")


def to_ros2(typestore: Typestore, msgtype: str, obj: Any) -> Any:
    """``obj`` (any message object with attributes) as a rosbags message of ``msgtype``."""
    kwargs = {
        name: _convert_value(typestore, node, _attribute(obj, name))
        for name, node in typestore.fielddefs[msgtype][1]
    }
    return typestore.types[msgtype](**kwargs)


def _convert_value(typestore: Typestore, node: Any, value: Any) -> Any:
    kind, argument = node
    name = getattr(kind, "name", str(kind))
    if name == "NAME":
        return to_ros2(typestore, argument, value)
    if name == "BASE":
        base = argument[0]
        if base == "string":
            return str(value)
        if base == "bool":
            return bool(value)
        if base.startswith("float"):
            return float(value)
        return int(value)
    inner, _ = argument
    inner_kind = getattr(inner[0], "name", str(inner[0]))
    if inner_kind == "NAME":
        return [to_ros2(typestore, inner[1], item) for item in value]
    base = inner[1][0]
    if base == "string":
        return [str(item) for item in value]
    dtype = _DTYPES[base]
    if isinstance(value, (bytes, bytearray, memoryview)):
        return np.frombuffer(value, dtype=dtype)
    return np.asarray(value, dtype=dtype)


def played_topics(source: BagSource, topics: Sequence[str] | None) -> list[str]:
    """The topics to play: the bag's (``topics`` None or empty) or ``topics``, all in the bag.

    Checked before any writer exists: one line names every topic the bag lacks and the ones
    it has, instead of publishing the others or stopping at the first.
    """
    if not topics:
        return list(source.topics)
    wanted = list(dict.fromkeys(topics))
    missing = [topic for topic in wanted if topic not in source.topics]
    if missing:
        raise missing_topic(source.path, ", ".join(missing), source.topics)
    return wanted


def check_rate(rate: float | None) -> None:
    """A play rate is a finite factor > 0; None (not infinity) is "as fast as possible"."""
    if rate is not None and not (math.isfinite(rate) and rate > 0):
        raise ConfigurationError(
            f"--rate must be a finite number > 0 (--fast plays as fast as possible), got {rate}"
        )


class BagPlayer:
    """Writers for a bag's topics on a transport; :meth:`play` publishes them on time."""

    def __init__(
        self,
        transport: DdsTransport,
        path: Path,
        topics: Sequence[str] | None = None,
        *,
        qos: QosProfile = PLAYBACK,
    ) -> None:
        self.path = Path(path)
        with BagSource(self.path) as source:
            self.format = source.format
            infos: dict[str, TopicInfo] = {
                t: source.topics[t] for t in played_topics(source, topics)
            }
        self.raw = self.format in RAW_FORMATS
        self._source = self._open()
        try:
            self.topics = {
                topic: PlayedTopic(
                    ros_topic_name(topic),
                    self._source.msgtype(topic),
                    self._source.typestore,
                    info.count,
                )
                for topic, info in infos.items()
            }
            self.writers: dict[str, RawWriter] = {
                topic: transport.writer(
                    played.name,
                    played.msgtype,
                    STATIC_TF if played.name == STATIC_TF_TOPIC else qos,  # latched, as recorded
                    typestore=played.typestore,
                )
                for topic, played in self.topics.items()
            }
        except BaseException:
            self._source.close()
            raise
        self.published = 0

    def _open(self) -> _RawSource | _DecodedSource:
        if self.raw:
            try:
                return _RawSource(self.path)
            except Exception:  # e.g. a cut-off MCAP storage file: BagSource reads what is there
                self.raw = False
        return _DecodedSource(self.path)

    def wait_matched(
        self,
        timeout_s: float,
        settle_s: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> list[str]:
        """Wait for subscribers; returns the topics that have none.

        Stops when every topic has a subscriber, or (once some have) when no further one
        appeared for ``settle_s`` (a remote participant's endpoints are discovered together;
        topics nobody subscribes to need not hold up the play), or after ``timeout_s``.
        """
        deadline = clock() + timeout_s
        seen: set[str] = set()
        changed = clock()
        while True:
            now = clock()
            matched = {topic for topic, writer in self.writers.items() if writer.matched() > 0}
            if matched != seen:
                seen, changed = matched, now
            missing = [topic for topic in self.writers if topic not in matched]
            if not missing or now >= deadline or (matched and now - changed >= settle_s):
                return missing
            time.sleep(0.05)

    def play(
        self,
        *,
        rate: float | None = 1.0,
        loop: bool = False,
        stop: threading.Event | None = None,
        clock: Callable[[], float] = time.monotonic,
        on_message: Callable[[str, int], None] | None = None,
    ) -> int:
        """Publish every message (again and again with ``loop``); returns how many."""
        check_rate(rate)
        stop = stop or threading.Event()
        topics = list(self.topics)
        while not stop.is_set():
            self._play_once(topics, rate, stop, clock, on_message)
            if not loop:
                break
            self._source.close()
            self._source = self._open()
        return self.published

    def _play_once(
        self,
        topics: list[str],
        rate: float | None,
        stop: threading.Event,
        clock: Callable[[], float],
        on_message: Callable[[str, int], None] | None,
    ) -> None:
        started: float | None = None
        first_log = 0
        stream = self._source.messages(topics)
        while not stop.is_set():
            try:
                item = next(stream, None)
            except DispevalError:
                raise
            except Exception as error:
                raise InputError(
                    f"{self.path}: reading stopped after {self.published} messages"
                    f" ({_one_line(error)})"
                ) from None
            if item is None:
                return
            topic, log_ns, payload = item
            if rate is not None:
                if started is None:
                    started, first_log = clock(), log_ns
                delay = started + (log_ns - first_log) / 1e9 / rate - clock()
                if delay > 0 and stop.wait(delay):
                    return
            self.writers[topic].write_cdr(payload)
            self.published += 1
            if on_message is not None:
                on_message(topic, log_ns)

    def finish(self, timeout_s: float = 2.0) -> None:
        """Wait (a little) for reliable subscribers to acknowledge, release the bag."""
        deadline = time.monotonic() + timeout_s
        for writer in self.writers.values():
            writer.wait_for_acks(max(0.0, deadline - time.monotonic()))
        self._source.close()
