"""Cyclone DDS with raw CDR payloads: one participant, ROS 2 topics, writers and reader threads.

The raw-CDR path
----------------
cyclonedds-python's ``DataWriter.write(sample)`` calls ``sample.serialize()`` (its Python CDR
machine) and hands the bytes to ``_clayer.ddspy_write(writer, bytes)``; ``DataReader.take()``
gets ``(bytes, SampleInfo)`` pairs from ``_clayer.ddspy_take`` and calls the type's Python
``deserialize``. The C layer's sertype ("ddspy") stores payloads as opaque byte buffers: on
write it copies the buffer (encapsulation header included) into a serdata, checks it against
the type's CDR program (``dds_stream_normalize``, a bounds check that skips over primitive
sequences) and sends it as it is; on receipt it keeps the bytes as they arrived (byte-swapped
in place if they came big-endian).

So this module keeps the DDS entities of cyclonedds-python (participant, topics with the ROS 2
type name and XTypes description from :mod:`dispeval_ros.dds.idl`, QoS, read conditions,
waitsets) and calls those two C entry points directly with payloads serialised by rosbags:
``typestore.serialize_cdr`` gives exactly the XCDR1 stream a ROS 2 node sends (header
``00 01 00 00``), zero-padded here to a multiple of 4 as ``rmw_cyclonedds_cpp`` pads it;
``typestore.deserialize_cdr`` decodes what ROS 2 nodes publish. Image data is copied with
``memcpy``, never packed element by element.

Readers are served by :class:`ReaderThread`: one thread per consumer waits on a waitset of read
conditions and a guard condition (no Python runs in Cyclone's receive threads, so a busy
scoring thread holding the GIL never stalls the network side), takes samples in batches,
decodes them with rosbags and calls the consumer's handler.
"""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from dispeval_ros.dds.environment import require_cyclonedds
from dispeval_ros.dds.idl import struct_for
from dispeval_ros.dds.wire import (
    QosProfile,
    dds_topic,
    normal_msgtype,
    pad_cdr,
    ros_topic_name,
    user_data,
)
from dispeval_ros.errors import ConfigurationError, DispevalError

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

TAKE_BATCH = 64
MAX_BLOCKING_NS = 1_000_000_000
"""How long a reliable write may block on a full history before it fails (rmw: forever)."""


class TransportError(DispevalError):
    """A DDS operation failed (the participant, a topic, a write or a take)."""


def humble_typestore() -> Typestore:
    """The ROS 2 Humble types of rosbags: what messages are built and decoded with by default."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def _dds_error(what: str, error: BaseException) -> TransportError:
    text = " ".join(str(error).split()) or type(error).__name__
    return TransportError(f"{what}: {text}")


@dataclass(frozen=True)
class Received:
    """One sample: the ROS topic, the decoded message, the raw payload and DDS sample info."""

    topic: str
    msg: Any
    payload: bytes
    info: Any


class DdsTransport:
    """One DDS participant on a domain, with ROS 2 topics, writers and readers.

    ``typestore`` (default: ROS 2 Humble) provides message types, CDR (de)serialisation and
    type hashes; each endpoint may name its own (the player uses the bag's).
    """

    def __init__(self, domain: int, typestore: Typestore | None = None) -> None:
        require_cyclonedds()
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.qos import Policy, Qos

        self.domain = domain
        self.typestore = typestore if typestore is not None else humble_typestore()
        self._lock = threading.Lock()
        self._topics: dict[str, tuple[Any, type]] = {}
        self._entities: list[Any] = []
        self._threads: list[ReaderThread] = []
        self._closed = False
        try:
            # ROS 2 participants announce their security enclave this way
            self.participant = DomainParticipant(domain, qos=Qos(Policy.Userdata(b"enclave=/;")))
        except Exception as error:
            raise _dds_error(
                f"cannot join DDS domain {domain} (check CYCLONEDDS_URI / --dds-config)", error
            ) from None

    # -- endpoints -------------------------------------------------------------------------

    def _topic(self, name: str, msgtype: str, typestore: Typestore) -> Any:
        from cyclonedds.topic import Topic

        dds_name = dds_topic(name)
        struct = struct_for(typestore, msgtype)
        with self._lock:
            existing = self._topics.get(dds_name)
            if existing is not None:
                if existing[1] is not struct:
                    raise ConfigurationError(
                        f"topic {ros_topic_name(name)} is already used with another type here"
                    )
                return existing[0]
            try:
                topic: Any = Topic(self.participant, dds_name, struct)
            except Exception as error:
                raise _dds_error(f"cannot create the DDS topic {dds_name}", error) from None
            self._topics[dds_name] = (topic, struct)
            self._entities.append(topic)
            return topic

    def writer(
        self,
        topic: str,
        msgtype: str,
        profile: QosProfile,
        typestore: Typestore | None = None,
    ) -> RawWriter:
        """A writer of ``msgtype`` on the ROS topic, with the type hash in its USER_DATA."""
        from cyclonedds.pub import DataWriter

        store = typestore if typestore is not None else self.typestore
        msgtype = normal_msgtype(msgtype)
        dds = self._topic(topic, msgtype, store)
        qos = endpoint_qos(profile, user_data(store, msgtype), writer=True)
        try:
            entity = DataWriter(self.participant, dds, qos)
        except Exception as error:
            raise _dds_error(f"cannot create a writer on {dds_topic(topic)}", error) from None
        self._entities.append(entity)
        return RawWriter(ros_topic_name(topic), msgtype, store, entity)

    def reader(
        self,
        topic: str,
        msgtype: str,
        profile: QosProfile,
        typestore: Typestore | None = None,
    ) -> RawReader:
        """A reader of ``msgtype`` on the ROS topic (served by a :class:`ReaderThread`)."""
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState
        from cyclonedds.sub import DataReader

        store = typestore if typestore is not None else self.typestore
        msgtype = normal_msgtype(msgtype)
        dds = self._topic(topic, msgtype, store)
        qos = endpoint_qos(profile, user_data(store, msgtype), writer=False)
        try:
            entity = DataReader(self.participant, dds, qos)
            condition = ReadCondition(
                entity, SampleState.NotRead | ViewState.Any | InstanceState.Any
            )
        except Exception as error:
            raise _dds_error(f"cannot create a reader on {dds_topic(topic)}", error) from None
        self._entities.extend((entity, condition))
        return RawReader(ros_topic_name(topic), msgtype, store, entity, condition)

    def reader_thread(
        self, name: str, on_error: Callable[[str], None] | None = None
    ) -> ReaderThread:
        """A new thread (not started) that serves the readers given to it."""
        thread = ReaderThread(self, name, on_error)
        self._threads.append(thread)
        return thread

    # -- shutdown --------------------------------------------------------------------------

    def close(self) -> None:
        """Stop every reader thread and delete every entity (remote peers see us leave)."""
        if self._closed:
            return
        self._closed = True
        for thread in self._threads:
            thread.stop(drain=False)
        for entity in reversed(self._entities):
            _delete(entity)
        self._entities.clear()
        self._topics.clear()
        _delete(self.participant)

    def __enter__(self) -> DdsTransport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _delete(entity: Any) -> None:
    """Delete a cyclonedds entity now (its own finaliser; later garbage collection is a no-op)."""
    with contextlib.suppress(Exception):  # already gone with its parent
        entity.__del__()


def endpoint_qos(profile: QosProfile, userdata: bytes, *, writer: bool) -> Any:
    """The cyclonedds QoS of an endpoint the way ``rmw_cyclonedds_cpp`` builds it."""
    from cyclonedds.qos import Policy, Qos

    history = (
        Policy.History.KeepAll if profile.depth is None else Policy.History.KeepLast(profile.depth)
    )
    policies: list[Any] = [
        Policy.Reliability.Reliable(max_blocking_time=MAX_BLOCKING_NS)
        if profile.reliable
        else Policy.Reliability.BestEffort,
        history,
        Policy.Durability.TransientLocal if profile.transient_local else Policy.Durability.Volatile,
        Policy.DataRepresentation(use_cdrv0_representation=True),
        Policy.Userdata(data=userdata),
    ]
    if writer:
        policies.append(Policy.WriterDataLifecycle(autodispose=False))
        if profile.transient_local:
            policies.append(
                Policy.DurabilityService(
                    cleanup_delay=0,
                    history=history,
                    max_samples=-1,
                    max_instances=-1,
                    max_samples_per_instance=-1,
                )
            )
    return Qos(*policies)


class RawWriter:
    """Publishes CDR payloads (or rosbags messages, serialised here) on one ROS topic."""

    def __init__(self, topic: str, msgtype: str, typestore: Typestore, entity: Any) -> None:
        from cyclonedds._clayer import ddspy_write, ddspy_write_ts

        self.topic = topic
        self.msgtype = msgtype
        self.typestore = typestore
        self.entity = entity
        self._ref = entity._ref
        self._write = ddspy_write
        self._write_ts = ddspy_write_ts
        self.written = 0

    def write_cdr(
        self, payload: bytes | bytearray | memoryview, timestamp_ns: int | None = None
    ) -> None:
        """Send one serialised message (encapsulation header first; XCDR1 only).

        ``timestamp_ns`` is the DDS source timestamp (default: now).
        """
        if len(payload) < 4 or payload[0] != 0 or payload[1] not in (0, 1):
            raise TransportError(
                f"{self.topic}: payload is not plain CDR (header {bytes(payload[:4]).hex()})"
            )
        data = pad_cdr(payload)
        if timestamp_ns is None:
            code = self._write(self._ref, data)
        else:
            code = self._write_ts(self._ref, data, int(timestamp_ns))
        if code < 0:
            raise TransportError(f"writing to {self.topic} failed (DDS return code {code})")
        self.written += 1

    def serialize(self, msg: Any) -> memoryview:
        """The CDR payload of a message of this writer's type."""
        return self.typestore.serialize_cdr(msg, self.msgtype)

    def publish(self, msg: Any, timestamp_ns: int | None = None) -> None:
        """Serialise with rosbags and send."""
        self.write_cdr(self.serialize(msg), timestamp_ns)

    def matched(self) -> int:
        """How many readers are matched now."""
        try:
            return int(self.entity.get_publication_matched_status().current_count)
        except Exception:  # deleted with its participant
            return 0

    def wait_for_acks(self, timeout_s: float) -> bool:
        """Block until reliable readers acknowledged everything (False on timeout)."""
        try:
            return bool(self.entity.wait_for_acks(int(timeout_s * 1e9)))
        except Exception:
            return False


class RawReader:
    """Takes CDR payloads from one ROS topic; :meth:`decode` turns them into rosbags messages."""

    def __init__(
        self, topic: str, msgtype: str, typestore: Typestore, entity: Any, condition: Any
    ) -> None:
        from cyclonedds._clayer import ddspy_take
        from cyclonedds.core import InstanceState, SampleState, ViewState

        self.topic = topic
        self.msgtype = msgtype
        self.typestore = typestore
        self.entity = entity
        self.condition = condition
        self._ref = entity._ref
        self._take = ddspy_take
        self._mask = SampleState.Any | ViewState.Any | InstanceState.Any

    def take(self, limit: int = TAKE_BATCH) -> list[tuple[bytes, Any]]:
        """Up to ``limit`` waiting samples as (payload, SampleInfo); never blocks."""
        result = self._take(self._ref, self._mask, limit)
        if isinstance(result, int):
            raise TransportError(f"taking from {self.topic} failed (DDS return code {result})")
        return [(data, info) for data, info in result if info.valid_data]

    def decode(self, payload: bytes) -> Any:
        """The rosbags message of a payload."""
        return self.typestore.deserialize_cdr(memoryview(payload), self.msgtype)  # no copy

    def matched(self) -> int:
        """How many writers are matched now."""
        try:
            return int(self.entity.get_subscription_matched_status().current_count)
        except Exception:  # deleted with its participant
            return 0


Handler = Callable[[Received], None]


class ReaderThread:
    """Serve readers from one thread: wait on their read conditions, take, decode, dispatch."""

    def __init__(
        self, transport: DdsTransport, name: str, on_error: Callable[[str], None] | None = None
    ) -> None:
        from cyclonedds.core import GuardCondition, WaitSet

        self.name = name
        self.on_error = on_error or _print_error
        self._waitset = WaitSet(transport.participant)
        self._guard = GuardCondition(transport.participant)
        self._waitset.attach(self._guard)
        transport._entities.extend((self._guard, self._waitset))
        self._entries: list[tuple[RawReader, Handler, bool]] = []
        self._stopping = False
        self._thread: threading.Thread | None = None
        self._serve_lock = threading.Lock()
        self.errors: dict[str, int] = {}
        self.received = 0

    def add(self, reader: RawReader, handler: Handler, *, decode: bool = True) -> None:
        """Call ``handler`` for every sample of ``reader`` (decoded unless ``decode`` is False)."""
        self._waitset.attach(reader.condition)
        self._entries.append((reader, handler, decode))

    def start(self) -> None:
        """Start serving."""
        self._thread = threading.Thread(target=self._run, name=f"dds-{self.name}", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stopping:
            try:
                self._waitset.wait(1_000_000_000)
            except Exception as error:  # the participant is gone
                self.on_error(f"{self.name}: waiting for data failed ({error})")
                return
            if self._stopping:
                return
            self.drain()

    def drain(self) -> int:
        """Take and dispatch everything waiting now; returns how many samples."""
        served = 0
        with self._serve_lock:
            for reader, handler, decode in self._entries:
                while True:
                    try:
                        samples = reader.take()
                    except TransportError as error:
                        self._error(reader.topic, str(error))
                        break
                    for payload, info in samples:
                        served += 1
                        self._dispatch(reader, handler, decode, payload, info)
                    if len(samples) < TAKE_BATCH:
                        break
        self.received += served
        return served

    def _dispatch(
        self, reader: RawReader, handler: Handler, decode: bool, payload: bytes, info: Any
    ) -> None:
        try:
            msg = reader.decode(payload) if decode else None
        except Exception as error:
            self._error(
                reader.topic, f"cannot decode a {reader.msgtype} on {reader.topic} ({error})"
            )
            return
        try:
            handler(Received(reader.topic, msg, payload, info))
        except DispevalError as error:
            self._error(reader.topic, f"{reader.topic}: {error}")
        except Exception as error:
            self._error(reader.topic, f"{reader.topic}: {type(error).__name__}: {error}")

    def _error(self, topic: str, message: str) -> None:
        count = self.errors.get(topic, 0) + 1
        self.errors[topic] = count
        if count == 1 or count % 100 == 0:
            suffix = "" if count == 1 else f" ({count} times so far)"
            self.on_error(" ".join(message.split()) + suffix)

    def stop(self, drain: bool = True) -> None:
        """Stop the thread; with ``drain``, dispatch what already arrived (in this thread)."""
        self._stopping = True
        with contextlib.suppress(Exception):
            self._guard.set(True)
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
        if drain:
            self.drain()


def _print_error(message: str) -> None:
    print(f"dispeval: {message}", file=sys.stderr, flush=True)
