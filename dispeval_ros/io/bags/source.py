"""``BagSource``: open any bag by its format (detected from the path and magic bytes)."""

from __future__ import annotations

import contextlib
import re
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from dispeval_ros.errors import DispevalError, InputError
from dispeval_ros.io.bags.common import (
    MCAP_MAGIC,
    ROS1_MAGIC,
    SQLITE_MAGIC,
    STORAGE_SUFFIXES,
    TopicInfo,
    Backend,
    missing_topic,
    one_line,
    ros2_type,
)
from dispeval_ros.io.bags.mcap_reader import McapBackend
from dispeval_ros.io.bags.rosbags_reader import RosbagsBackend

if TYPE_CHECKING:
    from types import TracebackType


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
        p for p in folder.iterdir() if p.is_file() and p.suffix in (".bag", *STORAGE_SUFFIXES)
    )


def _open(path: Path) -> tuple[str, Backend]:
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
            return "ros1", _guard(path, lambda: RosbagsBackend(files, path, ros1=True))
        if len(files) > 1:
            names = ", ".join(f.name for f in files)
            raise InputError(
                f"{path}: folder has no metadata.yaml and several bag files ({names});"
                " open one of them"
            )
        return _open_file(files[0])
    if path.suffix in STORAGE_SUFFIXES and (path.parent / "metadata.yaml").is_file():
        return _open(path.parent)
    return _open_file(path)


def _open_file(path: Path) -> tuple[str, Backend]:
    magic = _magic(path)
    if not magic:
        raise InputError(f"{path}: bag file is empty (0 bytes)")
    if path.suffix == ".bag" or magic.startswith(ROS1_MAGIC):
        if path.suffix != ".bag":
            raise InputError(f"{path}: looks like a ROS 1 bag; its name must end in .bag")
        return "ros1", _guard(path, lambda: RosbagsBackend([path], path, ros1=True))
    if path.suffix == ".mcap" or magic.startswith(MCAP_MAGIC):
        return "mcap", _guard(path, lambda: McapBackend(path, path))
    if path.suffix == ".db3" or magic.startswith(SQLITE_MAGIC):
        if path.suffix != ".db3":
            raise InputError(
                f"{path}: looks like a rosbag2 sqlite3 file; its name must end in .db3"
            )
        return "rosbag2-sqlite3", _guard(path, lambda: RosbagsBackend([path], path, ros1=False))
    raise InputError(
        f"{path}: not a bag (expected a rosbag2 folder with metadata.yaml, or a .db3, .mcap"
        " or .bag file)"
    )


def _open_rosbag2(folder: Path, fmt: str) -> Backend:
    mcaps = sorted(folder.glob("*.mcap")) if fmt == "rosbag2-mcap" else []
    storage = mcaps[0] if len(mcaps) == 1 else None
    try:
        return _guard(folder, lambda: RosbagsBackend([folder], folder, False, storage))
    except InputError:
        # rosbags refuses MCAP storage without a valid footer (a recorder that was killed):
        # fall back to scanning the storage file with mcap, which yields what is readable.
        # Only then: a bag whose metadata is broken stays an error.
        if fmt != "rosbag2-mcap" or len(mcaps) != 1 or not _lacks_end_magic(mcaps[0]):
            raise
        try:
            return McapBackend(mcaps[0], folder)
        except Exception:
            pass
        raise


def _lacks_end_magic(file: Path) -> bool:
    """Whether an MCAP file does not end with the magic bytes (it was cut off)."""
    try:
        with file.open("rb") as stream:
            size = stream.seek(0, 2)
            if size < len(MCAP_MAGIC):
                return True
            stream.seek(size - len(MCAP_MAGIC))
            return stream.read() != MCAP_MAGIC
    except OSError:
        return False


def _guard(path: Path, opener: Callable[[], Backend]) -> Backend:
    """Run ``opener``, turning any library exception into a one-line InputError."""
    try:
        return opener()
    except DispevalError:
        raise
    except Exception as exc:
        raise InputError(f"{path}: cannot read bag ({one_line(exc)})") from None


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
                raise missing_topic(self.path, topic, self.topics)
        if not wanted:
            return iter(())
        return self._backend.messages(wanted, start_ns, stop_ns, on_error)

    def log_times(self) -> Iterator[int]:
        """The log time of every message, in no set order, a time possibly more than once.

        One pass that decodes nothing (chunk by chunk where the bag is indexed), for planning
        by where the messages are; stops at damaged storage.
        """
        if self._closed:
            raise InputError(f"{self.path}: bag is closed")
        return self._backend.log_times()

    def serialized_messages(
        self, topics: Sequence[str]
    ) -> Iterator[tuple[str, int, bytes | memoryview]] | None:
        """``(topic, log time ns, serialized bytes)`` of ``topics`` in log-time order, unparsed.

        Only where the bag is read chunk by chunk from a memory map (indexed MCAP storage): the
        bytes are views of the map, no copy. None otherwise. Raises
        :class:`~dispeval_ros.io.bags.chunked_mcap.NotChunked` at a chunk it cannot read (the
        caller continues with a library reader; see
        :func:`~dispeval_ros.io.bags.chunked_mcap.fast_then_slow`).
        """
        chunked = self._backend.chunked
        if self._closed or chunked is None:
            return None
        return chunked.topic_messages(topics, None, None)

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
        raise missing_topic(source.path, topic, source.topics)
    wanted = [ros2_type(t) for t in ([msgtypes] if isinstance(msgtypes, str) else msgtypes)]
    if wanted and info.msgtype not in wanted:
        expected = " or ".join(wanted)
        raise InputError(
            f"{source.path}: topic {topic} has type {info.msgtype or 'unknown'},"
            f" expected {expected}"
        )
    return info


# -- writing --------------------------------------------------------------------------------
