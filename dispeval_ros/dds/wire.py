"""The ROS 2 conventions on the DDS wire, as ``rmw_cyclonedds_cpp`` follows them (no DDS import).

- A ROS topic ``/a/b`` is the DDS topic ``rt/a/b`` (``rt`` = ROS topic; services use
  ``rq``/``rr`` and are not used here).
- A message type ``pkg/msg/Type`` is the DDS type ``pkg::msg::dds_::Type_``.
- Payloads are XCDR1 (plain CDR): a 4-byte encapsulation header ``00 01 00 00`` (CDR,
  little-endian, no options) and the CDR stream, zero-padded to a multiple of 4 bytes as
  ``rmw_cyclonedds_cpp`` pads them. Endpoints accept only the XCDR1 representation.
- Since Jazzy, every endpoint carries ``typehash=RIHS01_<sha256 hex>;`` in its USER_DATA QoS
  (the hash of the type description, computed by rosbags); nodes warn about endpoints without
  one. Humble ignores it.
- Topics have no keys.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

from dispeval_ros.errors import ConfigurationError
from dispeval_ros.stream.topics import GROUPS_TOPIC, SCORES_TOPIC, VECTOR_LEAF, method_topic  # noqa: F401  (re-exported)

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

TOPIC_PREFIX = "rt"
CDR_LE_HEADER = b"\x00\x01\x00\x00"
"""Encapsulation of the payloads ROS 2 nodes publish: CDR (XCDR1), little-endian, no options."""
CDR_BE_HEADER = b"\x00\x00\x00\x00"

DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
FLOAT64_MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"

_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"
_TOPIC = re.compile(rf"/?{_TOKEN}(?:/{_TOKEN})*")
_MSGTYPE = re.compile(rf"({_TOKEN})/(?:(msg)/)?({_TOKEN})")
_DDS_TYPE = re.compile(rf"({_TOKEN})::(msg)::dds_::({_TOKEN})_")


def ros_topic_name(name: str) -> str:
    """The fully qualified ROS topic: ``a/b`` → ``/a/b`` (node namespace ``/``); validated.

    Tokens are letters, digits and underscores, not starting with a digit; substitutions
    (``~``, ``{node}``) are not supported because there is no node here.
    """
    if not _TOPIC.fullmatch(name):
        raise ConfigurationError(
            f"'{name}' is not a ROS 2 topic name (/a/b: letters, digits, '_', tokens not "
            "starting with a digit, no '//' and no trailing '/')"
        )
    return name if name.startswith("/") else "/" + name


def dds_topic(name: str) -> str:
    """The DDS topic of a ROS topic: ``/stereo/sgbm/disparity`` → ``rt/stereo/sgbm/disparity``."""
    return TOPIC_PREFIX + ros_topic_name(name)


def ros_topic(dds_name: str) -> str | None:
    """The ROS topic of a DDS topic (``rt/a/b`` → ``/a/b``), None for non-ROS topics."""
    if dds_name.startswith(TOPIC_PREFIX + "/") and _TOPIC.fullmatch(dds_name[len(TOPIC_PREFIX) :]):
        return dds_name[len(TOPIC_PREFIX) :]
    return None


def normal_msgtype(msgtype: str) -> str:
    """``pkg/msg/Type`` (also from ``pkg/Type``), validated."""
    match = _MSGTYPE.fullmatch(msgtype)
    if match is None:
        raise ConfigurationError(f"'{msgtype}' is not a ROS 2 message type (pkg/msg/Type)")
    return f"{match[1]}/msg/{match[3]}"


def dds_type_name(msgtype: str) -> str:
    """``stereo_msgs/msg/DisparityImage`` → ``stereo_msgs::msg::dds_::DisparityImage_``."""
    package, _, name = normal_msgtype(msgtype).split("/")
    return f"{package}::msg::dds_::{name}_"


def ros_type_name(dds_name: str) -> str | None:
    """``pkg::msg::dds_::Type_`` → ``pkg/msg/Type``; None for types that are not ROS 2's."""
    match = _DDS_TYPE.fullmatch(dds_name)
    return f"{match[1]}/msg/{match[3]}" if match else None


def type_hash(typestore: Typestore, msgtype: str) -> str:
    """``RIHS01_<hex>``: the ROS 2 type hash (REP 2011) of a type of ``typestore``."""
    try:
        return str(typestore.hash_rihs01(normal_msgtype(msgtype)))
    except KeyError as error:
        raise ConfigurationError(
            f"cannot hash {msgtype}: the type store lacks {error.args[0] if error.args else '?'}"
        ) from None


def user_data(typestore: Typestore, msgtype: str) -> bytes:
    """The USER_DATA of an endpoint as Jazzy's ``rmw_cyclonedds_cpp`` writes it."""
    return f"typehash={type_hash(typestore, msgtype)};".encode("ascii")


def parse_user_data(data: bytes) -> dict[str, str]:
    """``key=value;key=value;`` (ROS 2's USER_DATA encoding) → dict."""
    pairs = {}
    for item in data.decode("utf-8", "replace").split(";"):
        key, sep, value = item.partition("=")
        if sep and key:
            pairs[key] = value
    return pairs


def pad_cdr(payload: bytes | bytearray | memoryview) -> bytes | bytearray | memoryview:
    """The payload zero-padded to a multiple of 4 bytes (what ``rmw_cyclonedds_cpp`` sends).

    Readers ignore up to 3 trailing bytes; the padding is not announced in the options field,
    exactly as ROS 2 nodes do. No copy when no padding is needed.
    """
    extra = -len(payload) % 4
    return payload if extra == 0 else bytes(payload) + b"\x00" * extra


def vector_topic(method: str) -> str:
    """``/dispeval/<method>/vector`` (the method name must be a ROS name token)."""
    if not re.fullmatch(_TOKEN, method):
        raise ConfigurationError(
            f"method name '{method}' cannot be part of a ROS topic name; "
            "use letters, digits and '_' (not starting with a digit)"
        )
    return method_topic(method, VECTOR_LEAF)


@dataclass(frozen=True)
class QosProfile:
    """The QoS of an endpoint, in ROS 2 terms (``depth`` None = keep all)."""

    reliable: bool
    depth: int | None
    transient_local: bool = False

    def describe(self) -> str:
        """``reliable, keep-last 10, volatile`` style."""
        history = "keep-all" if self.depth is None else f"keep-last {self.depth}"
        return ", ".join(
            (
                "reliable" if self.reliable else "best-effort",
                history,
                "transient-local" if self.transient_local else "volatile",
            )
        )


SENSOR_DATA = QosProfile(reliable=False, depth=5)
"""Subscriptions to sensor streams (REP 2003, rclcpp's SensorDataQoS): match any publisher."""
RESULTS = QosProfile(reliable=True, depth=100)
"""Score publications: reliable, so a reliable summarizer gets every frame."""
LATCHED = QosProfile(reliable=True, depth=1, transient_local=True)
"""The latest groups: late subscribers get them at once."""
SUMMARIZER_INPUT = QosProfile(reliable=True, depth=None)
"""The summarizer's subscription to the scores: every frame, in order."""
STATIC_TF = QosProfile(reliable=True, depth=100, transient_local=True)
"""``/tf_static`` as tf2_ros's static broadcaster and listener use it: latched."""
STATIC_TF_TOPIC = "/tf_static"
DYNAMIC_TF = QosProfile(reliable=True, depth=100)
"""``/tf`` as tf2_ros's listener subscribes it (``DynamicListenerQoS``: reliable, keep-last
100, volatile; ros2/geometry2 tf2_ros/qos.hpp), for ``live --egomotion``."""
PLAYBACK = QosProfile(reliable=True, depth=10)
"""``ros2 bag play``'s default: reliable, keep-last 10, volatile (matches every subscriber)."""
