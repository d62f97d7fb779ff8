"""``BagWriter``: rosbag2 bags (metadata version 8, readable by Humble) and plain MCAP files."""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO, Literal

from dispeval_ros.errors import ConfigurationError, DispevalError, InputError
from dispeval_ros.io.bags.common import WRITE_FORMATS, one_line, ros2_type

if TYPE_CHECKING:
    from types import TracebackType

    from rosbags.typesys.store import Typestore


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
            raise InputError(f"{self.path}: cannot create bag ({one_line(exc)})") from None

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
        msgtype = ros2_type(msgtype)
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
            raise InputError(f"{self.path}: cannot add topic {name} ({one_line(exc)})") from None
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
                f" ({one_line(exc)})"
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
            raise InputError(f"{self.path}: cannot write to {topic} ({one_line(exc)})") from None

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
            raise InputError(f"{self.path}: cannot finish bag ({one_line(exc)})") from None
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
