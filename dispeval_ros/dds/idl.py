"""DDS type descriptions of ROS 2 messages, made from a rosbags typestore (needs cyclonedds).

Cyclone DDS needs a type for every topic: its name (``pkg::msg::dds_::Type_``), whether it has
keys (ROS 2 topics have none) and its XTypes description, from which the C library builds the
CDR program that checks ("normalises") every incoming and outgoing payload. These classes
provide exactly that and nothing else: samples never go through cyclonedds-python's Python
(de)serialiser, which packs sequences element by element (about 30 ms for one 1242×375
disparity image, against 0.3 ms for rosbags). Payloads are serialised by rosbags and handed
to the C layer as bytes (see :mod:`dispeval_ros.dds.transport`).

The mapping is rosidl's: ``byte`` → octet, ``char`` → uint8, ``T[n]`` → array, ``T[]`` and
``T[<=n]`` → sequences, ``string<=n`` → bounded string, nested messages → nested structs named
the ROS 2 way, and an empty message gets rosidl's ``structure_needs_at_least_one_member``.
"""

from __future__ import annotations

import keyword
import threading
from typing import TYPE_CHECKING, Any

from dispeval_ros.dds.wire import dds_type_name, normal_msgtype
from dispeval_ros.errors import ConfigurationError

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

_LOCK = threading.Lock()
_CACHE: dict[tuple[str, tuple[Any, ...]], type] = {}


def _base_types() -> dict[str, Any]:
    from cyclonedds.idl import types

    return {
        "bool": bool,
        "byte": types.byte,
        "char": types.uint8,
        "int8": types.int8,
        "uint8": types.uint8,
        "int16": types.int16,
        "uint16": types.uint16,
        "int32": types.int32,
        "uint32": types.uint32,
        "int64": types.int64,
        "uint64": types.uint64,
        "float32": types.float32,
        "float64": types.float64,
        "string": str,
    }


def _fields(typestore: Typestore, msgtype: str) -> list[tuple[str, Any]]:
    try:
        return list(typestore.fielddefs[msgtype][1])
    except KeyError:
        raise ConfigurationError(f"the type store has no message type {msgtype}") from None


def signature(typestore: Typestore, msgtype: str) -> tuple[Any, ...]:
    """The structure of a type with every nested type expanded (equal structure, equal key)."""

    def describe(node: Any) -> Any:
        kind, argument = node
        name = getattr(kind, "name", str(kind))
        if name == "NAME":
            return ("NAME", argument, signature(typestore, argument))
        if name in ("ARRAY", "SEQUENCE"):
            return (name, describe(argument[0]), argument[1])
        return (name, tuple(argument) if isinstance(argument, (list, tuple)) else argument)

    return tuple((field, describe(node)) for field, node in _fields(typestore, msgtype))


def struct_for(typestore: Typestore, msgtype: str) -> type:
    """The cyclonedds ``IdlStruct`` class describing ``msgtype`` as ROS 2 nodes put it on DDS."""
    msgtype = normal_msgtype(msgtype)
    key = (msgtype, signature(typestore, msgtype))
    with _LOCK:
        found = _CACHE.get(key)
        if found is None:
            found = _make(typestore, msgtype)
            _CACHE[key] = found
    return found


def _make(typestore: Typestore, msgtype: str) -> type:
    from cyclonedds.idl import make_idl_struct
    from cyclonedds.idl import types as idl_types

    types: Any = idl_types  # its generic aliases (array[T, n]…) are not typed as such

    base = _base_types()

    def convert(node: Any) -> Any:
        kind, argument = node
        name = getattr(kind, "name", str(kind))
        if name == "BASE":
            typename, bound = argument
            if typename == "string" and bound:
                return types.bounded_str[bound]
            if typename not in base:
                raise ConfigurationError(
                    f"{msgtype}: the field type '{typename}' cannot be sent over DDS here"
                )
            return base[typename]
        if name == "NAME":
            key = (normal_msgtype(argument), signature(typestore, argument))
            nested = _CACHE.get(key)
            if nested is None:
                nested = _make(typestore, key[0])
                _CACHE[key] = nested
            return nested
        if name == "ARRAY":
            return types.array[convert(argument[0]), argument[1]]
        if name == "SEQUENCE":
            inner, bound = argument
            return (
                types.sequence[convert(inner), bound] if bound else types.sequence[convert(inner)]
            )
        raise ConfigurationError(f"{msgtype}: unsupported field kind {name}")

    fields: dict[str, Any] = {}
    for field, node in _fields(typestore, msgtype):
        fields[field + "_" if keyword.iskeyword(field) else field] = convert(node)
    if not fields:
        fields["structure_needs_at_least_one_member"] = types.uint8
    class_name = msgtype.rsplit("/", 1)[1] + "_"
    return make_idl_struct(class_name, dds_type_name(msgtype), fields)
