"""Reading and writing bags without ROS: rosbag2 (sqlite3, MCAP), ROS 1 and plain MCAP.

:class:`BagSource` opens

- a rosbag2 folder (``metadata.yaml`` + ``.db3`` or ``.mcap`` files), or one of its storage
  files (the folder is opened), read with rosbags' ``AnyReader``;
- a ROS 1 ``.bag`` file, or a folder of split ``.bag`` files, read with ``AnyReader`` (the
  ROS 1 message definitions in the bag are converted by rosbags; field names stay ROS 1's);
- a plain MCAP file without rosbag2 metadata (what ``ros2 bag record`` leaves when it is killed,
  or what other MCAP writers produce), read with ``mcap`` and decoded by ``mcap_ros2``; its
  messages are attribute-access objects like rosbags' dataclasses. A file whose summary is
  missing or damaged is scanned from the start: the messages before the damage are yielded,
  then :class:`~dispeval_ros.errors.InputError` says where it broke. A rosbag2 MCAP bag whose
  storage file rosbags refuses (truncated) is read the same way.

Types are registered from each bag's own message definitions. Message type names are reported
in the ROS 2 form ``pkg/msg/Type``. Every problem (missing path, corrupt storage, undecodable
message) is an ``InputError`` with a one-line message naming the bag; no rosbags, mcap or
sqlite exception escapes.

:class:`BagWriter` writes rosbag2 bags (version 8, readable by ROS 2 Humble and later) in
sqlite3 or MCAP storage, or a single plain MCAP file with ``ros2msg`` schemas; messages are
CDR-serialised by rosbags.
"""

from __future__ import annotations

import contextlib
import heapq
import inspect
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO, Literal, Protocol

from dispeval_ros.errors import ConfigurationError, DispevalError, InputError

if TYPE_CHECKING:
    from types import TracebackType

    from rosbags.typesys.store import Typestore

__all__ = ["BAG_FORMATS", "WRITE_FORMATS", "BagSource", "BagWriter", "TopicInfo", "require_topic"]

#: Values of :attr:`BagSource.format`.
BAG_FORMATS = ("rosbag2-sqlite3", "rosbag2-mcap", "ros1", "mcap")
#: Formats :class:`BagWriter` writes.
WRITE_FORMATS = ("rosbag2-sqlite3", "rosbag2-mcap", "mcap")

_MCAP_MAGIC = b"\x89MCAP0\r\n"
_ROS1_MAGIC = b"#ROSBAG V2.0"
_SQLITE_MAGIC = b"SQLite format 3\x00"
_STORAGE_SUFFIXES = (".db3", ".mcap")
_MAXTIME = 2**63 - 1

MessageTuple = tuple[str, int, Any]


@dataclass(frozen=True)
class TopicInfo:
    """A topic of a bag: name, message type (``pkg/msg/Type``) and message count."""

    name: str
    msgtype: str
    count: int


def _one_line(exc: BaseException) -> str:
    """An exception's message on one line (its type name when it has none)."""
    text = " ".join(str(exc).split())
    if not text:
        return type(exc).__name__
    return text if len(text) <= 300 else text[:297] + "..."


def _ros2_type(name: str) -> str:
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


def _missing_topic(path: Path, topic: str, topics: dict[str, TopicInfo]) -> InputError:
    return InputError(f"{path} has no topic {topic}; topics: {_topic_list(topics)}")


# -- backends -------------------------------------------------------------------------------


class _Backend(Protocol):
    topics: dict[str, TopicInfo]
    start_ns: int
    end_ns: int
    message_count: int

    def messages(
        self,
        topics: Sequence[str],
        start_ns: int | None,
        stop_ns: int | None,
        on_error: Callable[[InputError], None] | None,
    ) -> Iterator[MessageTuple]: ...

    def close(self) -> None: ...


def _decode_failed(
    path: Path,
    topic: str,
    log_ns: int,
    exc: BaseException,
    on_error: Callable[[InputError], None] | None,
) -> None:
    """Raise (or report to ``on_error``) a message that cannot be deserialised."""
    error = InputError(
        f"{path}: cannot deserialize the message on {topic} at log time {log_ns} ns"
        f" ({_one_line(exc)})"
    )
    if on_error is None:
        raise error from None
    on_error(error)


class _RosbagsBackend:
    """rosbag2 folders, raw ``.db3`` files and ROS 1 bags through rosbags' ``AnyReader``."""

    def __init__(self, paths: list[Path], display: Path, ros1: bool) -> None:
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
                    _ros2_type(info.msgtype)
                    if info.msgtype
                    else " | ".join(sorted({_ros2_type(c.msgtype) for c in info.connections})),
                    int(info.msgcount),
                )
                for name, info in reader.topics.items()
            }
            self.message_count = int(reader.message_count)
            start, end = int(reader.start_time), int(reader.end_time)
        except BaseException:
            reader.close()
            raise
        empty = self.message_count == 0 or start >= _MAXTIME
        self.start_ns = 0 if empty else start
        self.end_ns = 0 if empty else end

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
        stream = reader.messages(connections, start=start_ns, stop=stop_ns)
        last: int | None = None
        while True:
            try:
                item = next(stream, None)
            except Exception as exc:
                where = "" if last is None else f" after log time {last} ns"
                raise InputError(f"{self.path}: bag is damaged{where} ({_one_line(exc)})") from None
            if item is None:
                return
            connection, log_ns, raw = item
            last = log_ns
            try:
                msg = reader.deserialize(raw, connection.msgtype)
            except Exception as exc:
                _decode_failed(self.path, connection.topic, log_ns, exc, on_error)
                continue
            yield connection.topic, log_ns, msg

    def close(self) -> None:
        if self._reader.stack is not None:
            self._reader.close()


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


class _McapBackend:
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
        try:
            self._reader = SeekingReader(self._stream, validate_crcs=True)  # type: ignore[arg-type]
            summary = self._summary()
            if summary is not None:
                self._indexed = True
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
            msgtype = _ros2_type(schema.name) if schema is not None else ""
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

    @staticmethod
    def _records(stream: _StrictFile) -> Iterator[Any]:
        """Every record from the start of ``stream``, chunks expanded, in file order."""
        from mcap.stream_reader import StreamReader

        stream.seek(0)
        return StreamReader(stream, validate_crcs=True).records  # type: ignore[arg-type]

    def _scan(self) -> dict[int, int]:
        """List schemas, channels and counts by reading the file; note where it is damaged."""
        from mcap.records import Channel, Message, Schema

        self._schemas = {}
        self._channels = {}
        counts: dict[int, int] = {}
        first, last, count = _MAXTIME, -1, 0
        previous = -1
        records = self._records(self._stream)
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
            self._damage = self._describe_damage(exc, count, last)
            if count == 0 and not self._channels:
                raise InputError(self._damage) from None
        self.message_count = count
        self.start_ns = first if count else 0
        self.end_ns = last + 1 if count else 0
        return counts

    def _describe_damage(self, exc: BaseException, count: int, last: int) -> str:
        from mcap.exceptions import EndOfFile

        if isinstance(exc, (EndOfFile, _TruncatedError)):
            what = "MCAP file is truncated (it ends before its footer)"
        else:
            what = f"MCAP file is damaged ({_one_line(exc)})"
        after = f" after {count} messages (last log time {last} ns)" if count else ""
        return f"{self.path}: {what}{after}"

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
        return decoder(data)

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
        stream = self._reader.iter_messages(topics=list(topics), **window)
        last: int | None = None
        while True:
            try:
                item = next(stream, None)
            except Exception as exc:
                where = "" if last is None else f" after log time {last} ns"
                raise InputError(
                    f"{self.path}: MCAP file is damaged{where} ({_one_line(exc)})"
                ) from None
            if item is None:
                return
            schema, channel, message = item
            last = message.log_time
            try:
                msg = self._decode(schema, channel, message.data)
            except Exception as exc:
                _decode_failed(self.path, channel.topic, message.log_time, exc, on_error)
                continue
            yield channel.topic, message.log_time, msg

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
        high = _MAXTIME + 1 if stop_ns is None else stop_ns
        schemas: dict[int, Any] = {}
        channels: dict[int, Any] = {}
        pending: list[tuple[int, int, str, Any]] = []
        damage: str | None = None
        count, last = 0, -1
        # A file handle of its own, so that several iterations may be interleaved.
        raw = self._file.open("rb")
        records = self._records(_StrictFile(raw))
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
                        _decode_failed(self.path, channel.topic, record.log_time, exc, on_error)
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
            damage = self._describe_damage(exc, count, last)
        finally:
            raw.close()
        if pending:
            heapq.heapify(pending)
            while pending:
                log_ns, _, topic, msg = heapq.heappop(pending)
                yield topic, log_ns, msg
        if damage is not None:
            raise InputError(damage)

    def close(self) -> None:
        self._raw.close()


# -- opening --------------------------------------------------------------------------------


def _magic(path: Path) -> bytes:
    try:
        with path.open("rb") as file:
            return file.read(16)
    except OSError as exc:
        raise InputError(f"{path}: cannot read bag ({exc.strerror or exc})") from None


def _storage_identifier(folder: Path) -> str:
    """``mcap`` or ``sqlite3`` from a rosbag2 folder's metadata (else from its files)."""
    try:
        text = (folder / "metadata.yaml").read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(
            f"{folder / 'metadata.yaml'}: cannot read bag metadata ({exc.strerror or exc})"
        ) from None
    found = re.search(r"storage_identifier:\s*['\"]?(\w+)", text)
    if found:
        return found.group(1)
    return "mcap" if any(folder.glob("*.mcap")) else "sqlite3"


def _bag_files(folder: Path) -> list[Path]:
    return sorted(
        p for p in folder.iterdir() if p.is_file() and p.suffix in (".bag", *_STORAGE_SUFFIXES)
    )


def _open(path: Path) -> tuple[str, _Backend]:
    """Recognise the bag at ``path`` and open it with the matching backend."""
    if not path.exists():
        raise InputError(f"{path}: bag not found")
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            storage = _storage_identifier(path)
            fmt = "rosbag2-mcap" if storage == "mcap" else "rosbag2-sqlite3"
            return fmt, _open_rosbag2(path, fmt)
        files = _bag_files(path)
        if not files:
            raise InputError(
                f"{path}: not a bag (expected a rosbag2 folder with metadata.yaml, or a .db3,"
                " .mcap or .bag file)"
            )
        if all(f.suffix == ".bag" for f in files):
            return "ros1", _guard(path, lambda: _RosbagsBackend(files, path, ros1=True))
        if len(files) > 1:
            names = ", ".join(f.name for f in files)
            raise InputError(
                f"{path}: folder has no metadata.yaml and several bag files ({names});"
                " open one of them"
            )
        return _open_file(files[0])
    if path.suffix in _STORAGE_SUFFIXES and (path.parent / "metadata.yaml").is_file():
        return _open(path.parent)
    return _open_file(path)


def _open_file(path: Path) -> tuple[str, _Backend]:
    magic = _magic(path)
    if not magic:
        raise InputError(f"{path}: bag file is empty (0 bytes)")
    if path.suffix == ".bag" or magic.startswith(_ROS1_MAGIC):
        if path.suffix != ".bag":
            raise InputError(f"{path}: looks like a ROS 1 bag; its name must end in .bag")
        return "ros1", _guard(path, lambda: _RosbagsBackend([path], path, ros1=True))
    if path.suffix == ".mcap" or magic.startswith(_MCAP_MAGIC):
        return "mcap", _guard(path, lambda: _McapBackend(path, path))
    if path.suffix == ".db3" or magic.startswith(_SQLITE_MAGIC):
        if path.suffix != ".db3":
            raise InputError(
                f"{path}: looks like a rosbag2 sqlite3 file; its name must end in .db3"
            )
        return "rosbag2-sqlite3", _guard(path, lambda: _RosbagsBackend([path], path, ros1=False))
    raise InputError(
        f"{path}: not a bag (expected a rosbag2 folder with metadata.yaml, or a .db3, .mcap"
        " or .bag file)"
    )


def _open_rosbag2(folder: Path, fmt: str) -> _Backend:
    try:
        return _guard(folder, lambda: _RosbagsBackend([folder], folder, ros1=False))
    except InputError:
        # rosbags refuses MCAP storage without a valid footer (a recorder that was killed):
        # fall back to scanning the storage file with mcap, which yields what is readable.
        # Only then: a bag whose metadata is broken stays an error.
        mcaps = sorted(folder.glob("*.mcap"))
        if fmt != "rosbag2-mcap" or len(mcaps) != 1 or not _lacks_end_magic(mcaps[0]):
            raise
        try:
            return _McapBackend(mcaps[0], folder)
        except Exception:
            pass
        raise


def _lacks_end_magic(file: Path) -> bool:
    """Whether an MCAP file does not end with the magic bytes (it was cut off)."""
    try:
        with file.open("rb") as stream:
            size = stream.seek(0, 2)
            if size < len(_MCAP_MAGIC):
                return True
            stream.seek(size - len(_MCAP_MAGIC))
            return stream.read() != _MCAP_MAGIC
    except OSError:
        return False


def _guard(path: Path, opener: Callable[[], _Backend]) -> _Backend:
    """Run ``opener``, turning any library exception into a one-line InputError."""
    try:
        return opener()
    except DispevalError:
        raise
    except Exception as exc:
        raise InputError(f"{path}: cannot read bag ({_one_line(exc)})") from None


class BagSource:
    """A bag opened for reading (a context manager; :meth:`close` releases the files).

    Attributes: ``path``, ``format`` (one of :data:`BAG_FORMATS`), ``topics`` (name →
    :class:`TopicInfo`), ``start_ns`` (first log time), ``end_ns`` (one past the last log time,
    so ``[start_ns, end_ns)`` holds every message; both 0 for an empty bag) and
    ``message_count``.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        fmt, self._backend = _open(self.path)
        self.format = fmt
        self.topics: dict[str, TopicInfo] = dict(sorted(self._backend.topics.items()))
        self.start_ns = self._backend.start_ns
        self.end_ns = self._backend.end_ns
        self.message_count = self._backend.message_count
        self._closed = False

    def messages(
        self,
        topics: Sequence[str],
        start_ns: int | None = None,
        stop_ns: int | None = None,
        *,
        on_error: Callable[[InputError], None] | None = None,
    ) -> Iterator[tuple[str, int, Any]]:
        """Yield ``(topic, log time ns, message)`` of ``topics`` in log-time order.

        Only messages with ``start_ns <= log time < stop_ns`` are read. A message that cannot
        be deserialised raises :class:`InputError` naming topic and log time, or, when
        ``on_error`` is given, is passed to it and skipped. Damaged storage always raises
        (after the messages before the damage).
        """
        if self._closed:
            raise InputError(f"{self.path}: bag is closed")
        wanted = [topics] if isinstance(topics, str) else list(topics)
        for topic in wanted:
            if topic not in self.topics:
                raise _missing_topic(self.path, topic, self.topics)
        if not wanted:
            return iter(())
        return self._backend.messages(wanted, start_ns, stop_ns, on_error)

    def close(self) -> None:
        """Release the bag's files (idempotent)."""
        if not self._closed:
            self._closed = True
            with contextlib.suppress(Exception):
                self._backend.close()

    def __enter__(self) -> BagSource:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> Literal[False]:
        self.close()
        return False

    def __repr__(self) -> str:
        return f"BagSource({str(self.path)!r}, format={self.format!r}, {len(self.topics)} topics)"


def require_topic(source: BagSource, topic: str, msgtypes: Sequence[str]) -> TopicInfo:
    """The topic's info, or InputError if the bag lacks it or it has another message type.

    ``msgtypes`` may be spelled ``pkg/Type`` or ``pkg/msg/Type``.
    """
    info = source.topics.get(topic)
    if info is None:
        raise _missing_topic(source.path, topic, source.topics)
    wanted = [_ros2_type(t) for t in ([msgtypes] if isinstance(msgtypes, str) else msgtypes)]
    if wanted and info.msgtype not in wanted:
        expected = " or ".join(wanted)
        raise InputError(
            f"{source.path}: topic {topic} has type {info.msgtype or 'unknown'},"
            f" expected {expected}"
        )
    return info


# -- writing --------------------------------------------------------------------------------


def _default_qos() -> list[Any]:
    """Reliable, volatile, keep-last-10: what ROS 2 image publishers offer by default."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    zero = QosTime(0, 0)
    return [
        Qos(
            QosHistory.KEEP_LAST,
            10,
            QosReliability.RELIABLE,
            QosDurability.VOLATILE,
            zero,
            zero,
            QosLiveliness.AUTOMATIC,
            zero,
            False,
        )
    ]


class BagWriter:
    """Write a bag: ``rosbag2-sqlite3`` / ``rosbag2-mcap`` folders or a plain ``mcap`` file.

    rosbag2 bags are version 8 (ROS 2 Humble reads them). Plain MCAP files use the ``ros2``
    profile, ``ros2msg`` schemas generated from the typestore and CDR messages. With
    ``compress`` (the default) MCAP chunks are zstd-compressed, as rosbag2's own MCAP storage
    does; sqlite3 storage is never compressed (rosbag2 would need its compression plugin).
    The default typestore is ROS 2 Humble's. A context manager: leaving the block
    closes the bag (also after an exception, so what was written stays readable).
    """

    def __init__(
        self,
        path: str | Path,
        format: str = "rosbag2-sqlite3",  # noqa: A002 - the option's natural name
        typestore: Typestore | None = None,
        *,
        compress: bool = True,
    ) -> None:
        if format not in WRITE_FORMATS:
            raise ConfigurationError(
                f"bag format must be one of {', '.join(WRITE_FORMATS)}, got '{format}'"
            )
        self.path = Path(path)
        self.format = format
        if self.path.exists():
            raise InputError(f"{self.path} exists; remove it or choose another path")
        if typestore is None:
            from rosbags.typesys import Stores, get_typestore

            typestore = get_typestore(Stores.ROS2_HUMBLE)
        self.typestore = typestore
        self.compress = compress
        self._topics: dict[str, tuple[str, Any]] = {}
        self._sequence = 0
        self._closed = False
        self._rosbag2: Any = None
        self._mcap: Any = None
        self._file: BinaryIO | None = None
        try:
            if format == "mcap":
                self._open_mcap()
            else:
                self._open_rosbag2()
        except DispevalError:
            raise
        except Exception as exc:
            raise InputError(f"{self.path}: cannot create bag ({_one_line(exc)})") from None

    def _open_rosbag2(self) -> None:
        from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if self.format == "rosbag2-mcap" else StoragePlugin.SQLITE3
        writer = Writer(self.path, version=8, storage_plugin=plugin)
        if self.compress and plugin == StoragePlugin.MCAP:
            writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        writer.open()
        self._rosbag2 = writer

    def _open_mcap(self) -> None:
        from mcap.writer import CompressionType, Writer

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = self.path.open("xb")
        compression = CompressionType.ZSTD if self.compress else CompressionType.NONE
        self._mcap = Writer(self._file, compression=compression)
        self._mcap.start(profile="ros2", library="dispeval_ros")

    def add_topic(self, name: str, msgtype: str) -> None:
        """Declare a topic and its message type (``pkg/msg/Type``); repeating it is a no-op."""
        msgtype = _ros2_type(msgtype)
        known = self._topics.get(name)
        if known is not None:
            if known[0] != msgtype:
                raise ConfigurationError(
                    f"{self.path}: topic {name} was added as {known[0]}, now as {msgtype}"
                )
            return
        self._check_open()
        if msgtype not in self.typestore.types:
            raise ConfigurationError(f"{self.path}: the typestore has no message type {msgtype}")
        try:
            if self._rosbag2 is not None:
                handle: Any = self._rosbag2.add_connection(
                    name,
                    msgtype,
                    typestore=self.typestore,
                    offered_qos_profiles=_default_qos(),
                )
            else:
                msgdef, _ = self.typestore.generate_msgdef(msgtype, ros_version=2)
                schema = self._mcap.register_schema(msgtype, "ros2msg", msgdef.encode())
                handle = self._mcap.register_channel(name, "cdr", schema)
        except Exception as exc:
            raise InputError(f"{self.path}: cannot add topic {name} ({_one_line(exc)})") from None
        self._topics[name] = (msgtype, handle)

    def write(self, topic: str, stamp_ns: int, msg: Any) -> None:
        """Write one message at log time ``stamp_ns``.

        A topic not added yet is added with the message's type when it is a rosbags message.
        """
        self._check_open()
        if topic not in self._topics:
            msgtype = getattr(msg, "__msgtype__", None)
            if not msgtype:
                raise ConfigurationError(f"{self.path}: add topic {topic} before writing to it")
            self.add_topic(topic, msgtype)
        msgtype, handle = self._topics[topic]
        try:
            data = self.typestore.serialize_cdr(msg, msgtype)
        except Exception as exc:
            raise InputError(
                f"{self.path}: cannot serialize the message for {topic} as {msgtype}"
                f" ({_one_line(exc)})"
            ) from None
        try:
            if self._rosbag2 is not None:
                self._rosbag2.write(handle, int(stamp_ns), data)
            else:
                self._sequence += 1
                self._mcap.add_message(
                    handle, int(stamp_ns), bytes(data), int(stamp_ns), self._sequence
                )
        except Exception as exc:
            raise InputError(f"{self.path}: cannot write to {topic} ({_one_line(exc)})") from None

    def _check_open(self) -> None:
        if self._closed:
            raise InputError(f"{self.path}: bag writer is closed")

    def close(self) -> None:
        """Finish the bag (index, metadata.yaml); idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._rosbag2 is not None:
                self._rosbag2.close()
            else:
                self._mcap.finish()
        except Exception as exc:
            raise InputError(f"{self.path}: cannot finish bag ({_one_line(exc)})") from None
        finally:
            if self._file is not None:
                self._file.close()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> Literal[False]:
        if exc_type is None:
            self.close()
        else:
            with contextlib.suppress(Exception):
                self.close()
        return False
