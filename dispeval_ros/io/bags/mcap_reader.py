"""Plain MCAP files (and damaged rosbag2 MCAP storage), read with ``mcap`` and ``mcap_ros2``.

A file whose summary is missing or damaged is scanned from the start: the messages before
the damage are yielded, then an ``InputError`` says where it broke.
"""

from __future__ import annotations

import contextlib
import heapq
import inspect
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO

from dispeval_ros.errors import DispevalError, InputError
from dispeval_ros.io.bags.chunked_mcap import (
    ChunkedMcap,
    NotChunked,
    fast_then_slow,
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


class _TruncatedError(EOFError):
    """A read returned fewer bytes than the record said: the file ends early."""


class _StrictFile:
    """A read-only file whose short reads raise, so a cut-off record is not taken as whole.

    A read past the end fails before reading, so a garbage record length never makes Python
    allocate gigabytes.
    """

    def __init__(self, file: BinaryIO) -> None:
        self._file = file
        self._size = file.seek(0, 2)
        file.seek(0)

    def read(self, size: int = -1) -> bytes:
        if size is not None and size > 0:
            left = self._size - self._file.tell()
            if 0 < left < size:
                raise _TruncatedError(f"file ends inside a record ({left} of {size} bytes)")
        return self._file.read(size)

    def seek(self, offset: int, whence: int = 0) -> int:
        return self._file.seek(offset, whence)

    def tell(self) -> int:
        return self._file.tell()

    def seekable(self) -> bool:
        return True

    def readable(self) -> bool:
        return True


def scan_records(stream: BinaryIO) -> Iterator[Any]:
    """Every record from the start of ``stream``, chunks expanded, in file order.

    Short reads raise (:class:`_StrictFile`), so a record cut off by a killed writer is damage.
    """
    from mcap.stream_reader import StreamReader

    strict = _StrictFile(stream)
    return StreamReader(strict, validate_crcs=True).records  # type: ignore[arg-type]


def damage_text(path: Path, exc: BaseException, count: int, last: int) -> str:
    """Where and how a scanned MCAP file broke: the one wording of the readers and digests."""
    from mcap.exceptions import EndOfFile

    if isinstance(exc, (EndOfFile, _TruncatedError)):
        what = "MCAP file is truncated (it ends before its footer)"
    else:
        what = f"MCAP file is damaged ({one_line(exc)})"
    after = f" after {count} messages (last log time {last} ns)" if count else ""
    return f"{path}: {what}{after}"


class McapBackend:
    """A single MCAP file read with ``mcap`` and decoded by ``mcap_ros2``.

    With a complete summary (chunk indexes and statistics) messages are read through the index
    in log-time order. Otherwise the file is scanned from the start: once here to list topics
    and counts and find any damage, and again by :meth:`messages`.
    """

    def __init__(self, file: Path, display: Path) -> None:
        from mcap.reader import SeekingReader
        from mcap_ros2.decoder import DecoderFactory

        self.path = display
        self._file = file
        self._raw = file.open("rb")
        self._stream = _StrictFile(self._raw)
        self._factory = DecoderFactory()
        self._decoders: dict[int, Callable[[bytes], Any]] = {}
        self._damage: str | None = None
        self._ordered = True
        self.chunked: ChunkedMcap | None = None
        try:
            self._reader = SeekingReader(self._stream, validate_crcs=True)  # type: ignore[arg-type]
            summary = self._summary()
            if summary is not None:
                self._indexed = True
                self.chunked = open_chunked(file, summary)
                self._channels = dict(summary.channels)
                self._schemas = dict(summary.schemas)
                stats = summary.statistics
                assert stats is not None
                counts = dict(stats.channel_message_counts)
                self.message_count = int(stats.message_count)
                self.start_ns = int(stats.message_start_time) if self.message_count else 0
                self.end_ns = int(stats.message_end_time) + 1 if self.message_count else 0
            else:
                self._indexed = False
                counts = self._scan()
        except BaseException:
            self._raw.close()
            raise
        self.topics: dict[str, TopicInfo] = {}
        for channel_id, channel in sorted(self._channels.items()):
            schema = self._schemas.get(channel.schema_id)
            msgtype = ros2_type(schema.name) if schema is not None else ""
            count = counts.get(channel_id, 0)
            previous = self.topics.get(channel.topic)
            if previous is not None:
                if previous.msgtype != msgtype:
                    msgtype = " | ".join(sorted({previous.msgtype, msgtype}))
                count += previous.count
            self.topics[channel.topic] = TopicInfo(channel.topic, msgtype, count)

    def _summary(self) -> Any:
        """The summary when it is complete enough to read through the index, else None."""
        try:
            summary = self._reader.get_summary()
        except Exception:
            return None
        if summary is None or not summary.chunk_indexes or summary.statistics is None:
            return None
        return summary

    def _scan(self) -> dict[int, int]:
        """List schemas, channels and counts by reading the file; note where it is damaged."""
        from mcap.records import Channel, Message, Schema

        self._schemas = {}
        self._channels = {}
        counts: dict[int, int] = {}
        first, last, count = MAX_TIME, -1, 0
        previous = -1
        records = scan_records(self._raw)
        try:
            for record in records:
                if isinstance(record, Message):
                    log = record.log_time
                    counts[record.channel_id] = counts.get(record.channel_id, 0) + 1
                    count += 1
                    first, last = min(first, log), max(last, log)
                    if log < previous:
                        self._ordered = False
                    previous = log
                elif isinstance(record, Schema):
                    self._schemas[record.id] = record
                elif isinstance(record, Channel):
                    self._channels[record.id] = record
        except Exception as exc:
            self._damage = damage_text(self.path, exc, count, last)
            if count == 0 and not self._channels:
                raise InputError(self._damage) from None
        self.message_count = count
        self.start_ns = first if count else 0
        self.end_ns = last + 1 if count else 0
        return counts

    def _decode(self, schema: Any, channel: Any, data: bytes) -> Any:
        decoder = self._decoders.get(channel.id)
        if decoder is None:
            made = self._factory.decoder_for(channel.message_encoding, schema)
            if made is None:
                encoding = schema.encoding if schema is not None else "no schema"
                raise ValueError(
                    f"messages encoded as '{channel.message_encoding}' with schema encoding"
                    f" '{encoding}' cannot be decoded (expected cdr with ros2msg schemas)"
                )
            decoder = made
            self._decoders[channel.id] = decoder
        return decoder(bytes(data) if isinstance(data, memoryview) else data)  # mcap_ros2: bytes

    def messages(
        self,
        topics: Sequence[str],
        start_ns: int | None,
        stop_ns: int | None,
        on_error: Callable[[InputError], None] | None,
    ) -> Iterator[MessageTuple]:
        if self._indexed:
            yield from self._indexed_messages(topics, start_ns, stop_ns, on_error)
        else:
            yield from self._scanned_messages(topics, start_ns, stop_ns, on_error)

    def _indexed_messages(
        self,
        topics: Sequence[str],
        start_ns: int | None,
        stop_ns: int | None,
        on_error: Callable[[InputError], None] | None,
    ) -> Iterator[MessageTuple]:
        if start_ns is not None and stop_ns is not None and stop_ns <= start_ns:
            return
        # mcap ≥ 1.3 names the window starting_at / ending_before; older ones start/end_time.
        if "starting_at" in inspect.signature(self._reader.iter_messages).parameters:
            window: dict[str, Any] = {"starting_at": start_ns, "ending_before": stop_ns}
        else:  # pragma: no cover - old mcap
            window = {"start_time": start_ns, "end_time": stop_ns}

        def library() -> Iterator[tuple[str, int, tuple[Any, Any, Any]]]:
            stream = self._reader.iter_messages(topics=list(topics), **window)
            return (
                (channel.topic, message.log_time, (schema, channel, message.data))
                for schema, channel, message in stream
            )

        chunked = self.chunked
        if chunked is None:
            payloads = library()
        else:
            fast = (
                (
                    self._channels[cid].topic,
                    log_ns,
                    (self._schemas.get(self._channels[cid].schema_id), self._channels[cid], raw),
                )
                for cid, log_ns, raw in chunked.messages(
                    chunked.channels_of(topics), start_ns, stop_ns
                )
            )
            payloads = fast_then_slow(fast, library)
        yield from decoded_messages(
            self.path, "MCAP file", payloads, lambda item: self._decode(*item), on_error
        )

    def _scanned_messages(
        self,
        topics: Sequence[str],
        start_ns: int | None,
        stop_ns: int | None,
        on_error: Callable[[InputError], None] | None,
    ) -> Iterator[MessageTuple]:
        """Messages in file order (sorted first if the file is not in log-time order)."""
        from mcap.records import Channel, Message, Schema

        wanted = set(topics)
        low = -1 if start_ns is None else start_ns
        high = MAX_TIME + 1 if stop_ns is None else stop_ns
        schemas: dict[int, Any] = {}
        channels: dict[int, Any] = {}
        pending: list[tuple[int, int, str, Any]] = []
        damage: str | None = None
        count, last = 0, -1
        # A file handle of its own, so that several iterations may be interleaved.
        raw = self._file.open("rb")
        records = scan_records(raw)
        try:
            for record in records:
                if isinstance(record, Message):
                    count += 1
                    last = max(last, record.log_time)
                    channel = channels.get(record.channel_id)
                    if channel is None:
                        raise ValueError(f"message on unknown channel {record.channel_id}")
                    if channel.topic not in wanted or not low <= record.log_time < high:
                        continue
                    try:
                        msg = self._decode(schemas.get(channel.schema_id), channel, record.data)
                    except Exception as exc:
                        decode_failed(self.path, channel.topic, record.log_time, exc, on_error)
                        continue
                    if self._ordered:
                        yield channel.topic, record.log_time, msg
                    else:
                        pending.append((record.log_time, len(pending), channel.topic, msg))
                elif isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
        except DispevalError:
            raise
        except Exception as exc:
            damage = damage_text(self.path, exc, count, last)
        finally:
            raw.close()
        if pending:
            heapq.heapify(pending)
            while pending:
                log_ns, _, topic, msg = heapq.heappop(pending)
                yield topic, log_ns, msg
        if damage is not None:
            raise InputError(damage)

    def log_times(self) -> Iterator[int]:
        """Every message's log time, the payloads left undecoded (a planning pass).

        Through the chunks where the file is indexed, else by scanning it up to any damage.
        """
        chunked = self.chunked
        if chunked is not None:
            with contextlib.suppress(NotChunked):
                yield from (
                    log_ns for _, log_ns, _ in chunked.messages(list(chunked.topics), None, None)
                )
                return
        if self._indexed:
            yield from (message.log_time for _, _, message in self._reader.iter_messages())
            return
        from mcap.records import Message

        with self._file.open("rb") as raw, contextlib.suppress(Exception):  # up to the damage
            for record in scan_records(raw):
                if isinstance(record, Message):
                    yield record.log_time

    def close(self) -> None:
        if self.chunked is not None:
            self.chunked.close()
        self._raw.close()


# -- opening --------------------------------------------------------------------------------
