"""rosbag2 (sqlite3, MCAP) and ROS 1 bags, read with rosbags' ``AnyReader``."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from dispeval_ros.errors import InputError
from dispeval_ros.io.bags.chunked_mcap import (
    NotChunked,
    fast_then_slow,
    mcap_summary,
    open_chunked,
)
from dispeval_ros.io.bags.common import (
    MAX_TIME,
    MessageTuple,
    TopicInfo,
    decode_failed,
    decoded_messages,
    one_line,
    ros2_type,
)


def _log_times(reader: Any) -> Iterator[int]:
    """A rosbags reader's log times from what it indexes, else from a pass over its messages.

    ROS 1 readers hold every message's time in their connection indexes; rosbag2 sqlite3
    storage has a timestamp column (queried without reading the payloads).
    """
    indexes = getattr(reader, "indexes", None)
    if isinstance(indexes, dict) and indexes:
        for entries in indexes.values():
            yield from (int(entry.time) for entry in entries)
        return
    storages = getattr(getattr(reader, "storage", None), "storages", None) or [None]
    databases: list[Any] = [getattr(storage, "dbconn", None) for storage in storages]
    if None not in databases:
        try:
            query = "SELECT timestamp FROM messages"
            times = [int(row[0]) for database in databases for row in database.execute(query)]
        except Exception:  # another layout: read the messages
            times = None
        if times is not None:
            yield from times
            return
    yield from (log_ns for _, log_ns, _ in reader.messages())


class RosbagsBackend:
    """rosbag2 folders, raw ``.db3`` files and ROS 1 bags through rosbags' ``AnyReader``.

    ``storage``: the rosbag2 bag's one MCAP storage file, read chunk by chunk from a memory
    map where it can be (see :mod:`~dispeval_ros.io.bags.chunked_mcap`), the messages
    deserialised by rosbags as they would be otherwise.
    """

    def __init__(
        self, paths: list[Path], display: Path, ros1: bool, storage: Path | None = None
    ) -> None:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        self.path = display
        default = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        self._reader = AnyReader(paths, default_typestore=default)
        self._reader.open()
        reader = self._reader
        try:
            self.topics = {
                name: TopicInfo(
                    name,
                    ros2_type(info.msgtype)
                    if info.msgtype
                    else " | ".join(sorted({ros2_type(c.msgtype) for c in info.connections})),
                    int(info.msgcount),
                )
                for name, info in reader.topics.items()
            }
            self.message_count = int(reader.message_count)
            start, end = int(reader.start_time), int(reader.end_time)
        except BaseException:
            reader.close()
            raise
        empty = self.message_count == 0 or start >= MAX_TIME
        self.start_ns = 0 if empty else start
        self.end_ns = 0 if empty else end
        # Messages (or files) compressed by rosbag2 itself, not by MCAP chunks, are decompressed
        # by rosbags' reader: not read here.
        modes = {str(getattr(r, "compression_mode", None)).lower() for r in reader.readers}
        plain = not modes & {"message", "file"}
        self.chunked = (
            open_chunked(storage, mcap_summary(storage)) if storage is not None and plain else None
        )

    def messages(
        self,
        topics: Sequence[str],
        start_ns: int | None,
        stop_ns: int | None,
        on_error: Callable[[InputError], None] | None,
    ) -> Iterator[MessageTuple]:
        reader = self._reader
        connections = [c for c in reader.connections if c.topic in topics]
        if not connections:
            return

        def library() -> Iterator[tuple[str, int, tuple[Any, str]]]:
            stream = reader.messages(connections, start=start_ns, stop=stop_ns)
            return (
                (connection.topic, log_ns, (raw, connection.msgtype))
                for connection, log_ns, raw in stream
            )

        chunked = self.chunked
        msgtypes = {c.topic: c.msgtype for c in connections}
        if chunked is None or len(msgtypes) != len(connections):  # one type per topic, or not
            payloads = library()
        else:
            fast = (
                (topic, log_ns, (raw, msgtypes[topic]))
                for topic, log_ns, raw in chunked.topic_messages(msgtypes, start_ns, stop_ns)
            )
            payloads = fast_then_slow(fast, library)
        yield from decoded_messages(
            self.path, "bag", payloads, lambda item: reader.deserialize(*item), on_error
        )

    def log_times(self) -> Iterator[int]:
        """Every message's log time, the payloads left undeserialised (a planning pass)."""
        chunked = self.chunked
        if chunked is not None:
            with contextlib.suppress(NotChunked):
                yield from (log_ns for _, log_ns, _ in chunked.messages(list(chunked.topics), None, None))
                return
        for reader in self._reader.readers:
            yield from _log_times(reader)

    def close(self) -> None:
        if self.chunked is not None:
            self.chunked.close()
        if self._reader.stack is not None:
            self._reader.close()
