"""Indexed MCAP files read chunk by chunk from a memory map, without copying any message.

rosbags and mcap read a chunk into a new ``bytes`` object and then copy each message out of it
again: two copies of every byte, about as long as deserialising (1.5 ms per 1242×375 frame
of four maps). This reader maps the file, finds the chunks through the summary's chunk
indexes and hands out each message as a ``memoryview`` of the map (of the decompressed bytes
for compressed chunks), in the order both libraries give: by log time, then chunk offset,
then place in the chunk.

It only reads what it recognises: a file without a complete summary is not opened here
(:func:`open_chunked` gives None), and a chunk that does not match its index (record type,
lengths, compression, CRC) raises :class:`NotChunked` before any of its messages is yielded,
so the caller can let the library reader take over from that message and report the damage
in its own words (:func:`fast_then_slow`).

The file must not shrink while it is mapped (a bag being truncated while read): reading past
its new end would end the process.
"""

from __future__ import annotations

import contextlib
import heapq
import mmap
import struct
import zlib
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from dispeval_ros.io.bags.common import MAX_TIME

_CHUNK_OPCODE = 0x06
_MESSAGE_OPCODE = 0x05
_RECORD_HEAD = struct.Struct("<BQ")  # opcode, length
_CHUNK_HEAD = struct.Struct("<QQQI")  # start, end, uncompressed size, uncompressed CRC
_MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel, sequence, log time, publish time
_T = TypeVar("_T")


class NotChunked(Exception):
    """A chunk this reader does not read (damaged, or a layout it does not know)."""


def _decompress(compression: str, data: memoryview) -> memoryview:
    """A chunk's records, decompressed (as the libraries do: lz4 frames, zstd)."""
    if compression == "":
        return data
    if compression == "lz4":
        import lz4.frame

        raw = lz4.frame.decompress(data)
    elif compression == "zstd":
        raw = _zstd_decompress(data)
    else:
        raise NotChunked(f"unknown chunk compression {compression!r}")
    return memoryview(raw)


def _zstd_decompress(data: memoryview) -> bytes:
    try:
        from compression import zstd  # Python ≥ 3.14
    except ImportError:
        from backports import zstd  # a dependency of rosbags
    return bytes(zstd.decompress(data))


@dataclass(frozen=True)
class _ChunkIndex:
    start: int
    end: int
    offset: int
    length: int
    channels: frozenset[int]


class ChunkedMcap:
    """One indexed MCAP file mapped into memory; :meth:`messages` yields raw message bytes."""

    def __init__(self, path: Path, chunks: Sequence[_ChunkIndex], topics: dict[int, str]) -> None:
        self.path = path
        self._chunks = list(chunks)
        self.topics = topics
        """Channel id → topic."""
        with path.open("rb") as file:
            self._map = mmap.mmap(file.fileno(), 0, access=mmap.ACCESS_READ)
        self._size = len(self._map)
        for chunk in self._chunks:
            if chunk.offset < 0 or chunk.offset + chunk.length > self._size:
                self.close()
                raise NotChunked("a chunk index points outside the file")

    def channels_of(self, topics: Iterable[str]) -> list[int]:
        """The ids of the channels on ``topics``."""
        wanted = set(topics)
        return [channel for channel, topic in self.topics.items() if topic in wanted]

    def topic_messages(
        self, topics: Iterable[str], start_ns: int | None, stop_ns: int | None
    ) -> Iterator[tuple[str, int, memoryview]]:
        """``(topic, log time, message bytes)`` of ``topics``, as :meth:`messages` gives them."""
        for channel, log_ns, data in self.messages(self.channels_of(topics), start_ns, stop_ns):
            yield self.topics[channel], log_ns, data

    def messages(
        self, channels: Iterable[int], start_ns: int | None, stop_ns: int | None
    ) -> Iterator[tuple[int, int, memoryview]]:
        """``(channel id, log time, message bytes)`` of ``channels`` with log time in the window.

        In log-time order, ties in chunk then file order. Raises :class:`NotChunked` when a
        chunk cannot be read, before yielding any of its messages.
        """
        wanted = frozenset(channels)
        low = -1 if start_ns is None else start_ns
        high = MAX_TIME + 1 if stop_ns is None else stop_ns
        sources = [
            self._chunk_messages(chunk, wanted, low, high)
            for chunk in self._chunks
            if chunk.channels & wanted and chunk.end >= low and chunk.start < high
        ]
        for _log, _offset, index, channel, log_ns, data in heapq.merge(*sources):
            if index >= 0:
                yield channel, log_ns, data

    def _chunk_messages(
        self, chunk: _ChunkIndex, wanted: frozenset[int], low: int, high: int
    ) -> Iterator[tuple[int, int, int, int, int, Any]]:
        """A chunk's wanted messages, sorted; first a placeholder at its start time.

        The placeholder keeps the chunk unread until the merge reaches its time.
        """
        yield chunk.start, chunk.offset, -1, 0, 0, None
        records, offset = self._records(chunk), chunk.offset
        found = []
        position, end, index = 0, len(records), 0
        while position < end:
            if end - position < _RECORD_HEAD.size:
                raise NotChunked("a record is cut off at the end of its chunk")
            opcode, length = _RECORD_HEAD.unpack_from(records, position)
            body = position + _RECORD_HEAD.size
            position = body + length
            if position > end:
                raise NotChunked("a record runs past the end of its chunk")
            if opcode == _MESSAGE_OPCODE:
                if length < _MESSAGE_HEAD.size:
                    raise NotChunked("a message record is too short")
                channel, _, log_ns, _ = _MESSAGE_HEAD.unpack_from(records, body)
                if channel in wanted and low <= log_ns < high:
                    data = records[body + _MESSAGE_HEAD.size : position]
                    found.append((log_ns, offset, index, channel, log_ns, data))
            index += 1
        found.sort(key=lambda item: item[0])  # stable: file order for equal log times
        yield from found

    def _records(self, chunk: _ChunkIndex) -> memoryview:
        """The chunk's records, checked against its record header (and CRC, when it has one)."""
        try:
            return self._checked_records(chunk)
        except NotChunked:
            raise
        except Exception as error:  # struct, decompression: the library reader says it better
            raise NotChunked(str(error)) from None

    def _checked_records(self, chunk: _ChunkIndex) -> memoryview:
        view = memoryview(self._map)[chunk.offset : chunk.offset + chunk.length]
        opcode, length = _RECORD_HEAD.unpack_from(view, 0)
        if opcode != _CHUNK_OPCODE or _RECORD_HEAD.size + length != chunk.length:
            raise NotChunked("the chunk index does not point at its chunk")
        at = _RECORD_HEAD.size
        _, _, size, crc = _CHUNK_HEAD.unpack_from(view, at)
        at += _CHUNK_HEAD.size
        (name_length,) = struct.unpack_from("<I", view, at)
        at += 4
        compression = bytes(view[at : at + name_length]).decode("utf-8", "replace")
        at += name_length
        (stored,) = struct.unpack_from("<Q", view, at)
        at += 8
        if at + stored > len(view):
            raise NotChunked("chunk records run past the chunk")
        records = _decompress(compression, view[at : at + stored])
        if len(records) != size:
            raise NotChunked("chunk size does not match its record")
        if crc and zlib.crc32(records) != crc:
            raise NotChunked("chunk CRC mismatch")
        return records

    def close(self) -> None:
        """Unmap the file (left to the collector while messages still point into it)."""
        with contextlib.suppress(BufferError):
            self._map.close()


def mcap_summary(path: Path) -> Any:
    """The summary of the MCAP file at ``path`` (mcap's ``Summary``), or None if unreadable."""
    from mcap.reader import SeekingReader

    try:
        with path.open("rb") as file:
            return SeekingReader(file).get_summary()
    except Exception:  # no summary, damaged: the library reader is used (and reports it)
        return None


def open_chunked(path: Path, summary: Any) -> ChunkedMcap | None:
    """The chunked reader of an MCAP file given its summary (mcap's ``Summary``), or None.

    None when the summary has no chunk index, or a chunk without message indexes (rosbags
    skips those, mcap reads them) or in a compression this reader lacks.
    """
    if summary is None or not summary.chunk_indexes:
        return None
    chunks = []
    for index in summary.chunk_indexes:
        if index.compression not in ("", "lz4", "zstd") or not index.message_index_offsets:
            return None
        chunks.append(
            _ChunkIndex(
                int(index.message_start_time),
                int(index.message_end_time),
                int(index.chunk_start_offset),
                int(index.chunk_length),
                frozenset(index.message_index_offsets),
            )
        )
    topics = {int(channel_id): channel.topic for channel_id, channel in summary.channels.items()}
    try:
        return ChunkedMcap(path, chunks, topics)
    except (OSError, ValueError, NotChunked):
        return None


def fast_then_slow(fast: Iterator[_T], slow: Callable[[], Iterator[_T]]) -> Iterator[_T]:
    """``fast``'s items; if it raises :class:`NotChunked`, ``slow``'s from the same place on.

    Both yield the same items in the same order, so the slow reader takes over after the
    items already yielded (and reports any damage as it always does).
    """
    done = 0
    try:
        for item in fast:
            yield item
            done += 1
        return
    except NotChunked:
        pass
    stream = slow()
    for _ in range(done):
        next(stream, None)
    yield from stream
