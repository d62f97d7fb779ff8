"""What every bag reader shares: formats, topic records, one-line errors."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from dispeval_ros.errors import InputError

if TYPE_CHECKING:
    from dispeval_ros.io.bags.chunked_mcap import ChunkedMcap


#: Values of :attr:`BagSource.format`.
BAG_FORMATS = ("rosbag2-sqlite3", "rosbag2-mcap", "ros1", "mcap")
#: Formats :class:`BagWriter` writes.
WRITE_FORMATS = ("rosbag2-sqlite3", "rosbag2-mcap", "mcap")

MCAP_MAGIC = b"\x89MCAP0\r\n"
ROS1_MAGIC = b"#ROSBAG V2.0"
SQLITE_MAGIC = b"SQLite format 3\x00"
STORAGE_SUFFIXES = (".db3", ".mcap")
MAX_TIME = 2**63 - 1

MessageTuple = tuple[str, int, Any]


@dataclass(frozen=True)
class TopicInfo:
    """A topic of a bag: name, message type (``pkg/msg/Type``) and message count."""

    name: str
    msgtype: str
    count: int


def one_line(exc: BaseException) -> str:
    """An exception's message on one line (its type name when it has none)."""
    text = " ".join(str(exc).split())
    if not text:
        return type(exc).__name__
    return text if len(text) <= 300 else text[:297] + "..."


def ros2_type(name: str) -> str:
    """``pkg/Type`` or ``pkg/msg/Type`` → ``pkg/msg/Type`` (other names unchanged)."""
    parts = [part for part in name.split("/") if part]
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return "/".join(parts) if parts else name


def _topic_list(topics: dict[str, TopicInfo]) -> str:
    if not topics:
        return "none"
    return ", ".join(
        f"{info.name} ({info.msgtype or 'unknown type'}, {info.count} msgs)"
        for info in topics.values()
    )


def missing_topic(path: Path, topic: str, topics: dict[str, TopicInfo]) -> InputError:
    return InputError(f"{path} has no topic {topic}; topics: {_topic_list(topics)}")


# -- backends -------------------------------------------------------------------------------


class Backend(Protocol):
    topics: dict[str, TopicInfo]
    start_ns: int
    end_ns: int
    message_count: int
    chunked: ChunkedMcap | None
    """The storage file read chunk by chunk from a memory map, where it can be."""

    def messages(
        self,
        topics: Sequence[str],
        start_ns: int | None,
        stop_ns: int | None,
        on_error: Callable[[InputError], None] | None,
    ) -> Iterator[MessageTuple]: ...

    def log_times(self) -> Iterator[int]:
        """Every message's log time, unordered, a time possibly twice (cheap: not decoded)."""
        ...

    def close(self) -> None: ...


def decoded_messages(
    path: Path,
    what: str,
    stream: Iterator[tuple[str, int, Any]],
    decode: Callable[[Any], Any],
    on_error: Callable[[InputError], None] | None,
) -> Iterator[MessageTuple]:
    """``(topic, log_ns, payload)`` of a reader's ``stream`` with each payload decoded.

    A reading error ends the stream as one line (``what``, e.g. "bag", is damaged after the
    last log time read); a payload that cannot be decoded goes to :func:`decode_failed`.
    """
    last: int | None = None
    while True:
        try:
            item = next(stream, None)
        except Exception as exc:
            where = "" if last is None else f" after log time {last} ns"
            raise InputError(f"{path}: {what} is damaged{where} ({one_line(exc)})") from None
        if item is None:
            return
        topic, log_ns, payload = item
        last = log_ns
        try:
            msg = decode(payload)
        except Exception as exc:
            decode_failed(path, topic, log_ns, exc, on_error)
            continue
        yield topic, log_ns, msg


def decode_failed(
    path: Path,
    topic: str,
    log_ns: int,
    exc: BaseException,
    on_error: Callable[[InputError], None] | None,
) -> None:
    """Raise (or report to ``on_error``) a message that cannot be deserialised."""
    error = InputError(
        f"{path}: cannot deserialize the message on {topic} at log time {log_ns} ns"
        f" ({one_line(exc)})"
    )
    if on_error is None:
        raise error from None
    on_error(error)
