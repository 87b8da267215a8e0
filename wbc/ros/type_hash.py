"""RIHS01 type hashes of the messages (REP 2011), as ROS 2 advertises them in DDS user data.

Since Iron, every ROS 2 publisher and subscription carries ``typehash=RIHS01_<64 hex>;`` in
the USER_DATA QoS of its DDS endpoint (``rmw_dds_common::encode_type_hash_for_user_data_qos``),
and ``ros2 topic info -v`` shows it. The hash is the SHA-256 of a JSON text of the type's
description -- the type and, sorted by name, every type it refers to, each a list of fields
``{"name", "type": {"type_id", "capacity", "string_capacity", "nested_type_name"}}`` -- written
with the separators ``", "`` and ``": "`` (``rosidl_generator_type_description``). The field
type ids are those of ``type_description_interfaces/msg/FieldType``: the element type's id,
plus 48 for a fixed array, 96 for a bounded and 144 for an unbounded sequence.
"""

from __future__ import annotations

import hashlib
import json
import typing
from typing import Any

import cyclonedds.idl.types as idl
from cyclonedds.idl import IdlStruct

from .messages import CHAR_FIELDS, ROS_NAMES

RIHS01_PREFIX = "RIHS01_"
#: FieldType ids of the element types (type_description_interfaces/msg/FieldType.msg)
ELEMENT_IDS = {"nested": 1, "int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7, "int64": 8,
               "uint64": 9, "float32": 10, "float64": 11, "char": 13, "wchar": 14, "bool": 15, "byte": 16,
               "string": 17, "bounded_string": 21}
ARRAY, BOUNDED_SEQUENCE, UNBOUNDED_SEQUENCE = 48, 96, 144  #: added to the element's id
_PYTHON_TYPES = {str: "string", float: "float64", int: "int64", bool: "bool"}

FieldType = dict[str, Any]


def type_hash(message: type[IdlStruct]) -> str:
    """The RIHS01 hash ``"RIHS01_<64 hex digits>"`` of a message type of :mod:`wbc.ros.messages`."""
    referenced: dict[str, type[IdlStruct]] = {}
    _collect(message, referenced)
    description = {
        "type_description": _individual(message),
        "referenced_type_descriptions": [_individual(referenced[name]) for name in sorted(referenced)],
    }
    text = json.dumps(description, ensure_ascii=True, separators=(", ", ": "), sort_keys=False)
    return RIHS01_PREFIX + hashlib.sha256(text.encode("utf-8")).hexdigest()


def user_data(message: type[IdlStruct]) -> bytes:
    """The USER_DATA of a ROS 2 endpoint of ``message``: ``b"typehash=RIHS01_...;"``."""
    return f"typehash={type_hash(message)};".encode("ascii")


def _fields(message: type[IdlStruct]) -> dict[str, Any]:
    return typing.get_type_hints(message, include_extras=True)


def _collect(message: type[IdlStruct], referenced: dict[str, type[IdlStruct]]) -> None:
    """Every message type ``message`` refers to, directly or not, by ROS name."""
    for hint in _fields(message).values():
        nested = _field_type(hint)["nested"]
        if nested is not None and ROS_NAMES[nested] not in referenced:
            referenced[ROS_NAMES[nested]] = nested
            _collect(nested, referenced)


def _individual(message: type[IdlStruct]) -> dict[str, Any]:
    fields = []
    for name, hint in _fields(message).items():
        kind = _field_type(hint)
        nested = kind.pop("nested")
        kind["nested_type_name"] = "" if nested is None else ROS_NAMES[nested]
        if (message, name) in CHAR_FIELDS:  # declared char, serialized as uint8
            kind["type_id"] += ELEMENT_IDS["char"] - ELEMENT_IDS["uint8"]
        fields.append({"name": name, "type": kind})
    return {"type_name": ROS_NAMES[message], "fields": fields}


def _field_type(hint: Any) -> FieldType:
    """``{"type_id", "capacity", "string_capacity", "nested"}`` of a field annotation (``nested``:
    the message class of a nested field, else None)."""
    holder = typing.get_args(hint)[1] if typing.get_origin(hint) is typing.Annotated else None
    if isinstance(holder, (idl.sequence, idl.array)):
        element = _element(holder.subtype)
        if isinstance(holder, idl.array):
            offset, capacity = ARRAY, holder.length
        else:
            offset, capacity = (BOUNDED_SEQUENCE, holder.max_length) if holder.max_length else (UNBOUNDED_SEQUENCE, 0)
        return {"type_id": element["type_id"] + offset, "capacity": capacity,
                "string_capacity": element["string_capacity"], "nested": element["nested"]}
    return _element(hint)


def _element(hint: Any) -> FieldType:
    """The field type of a single (not array or sequence) element."""
    if isinstance(hint, type) and issubclass(hint, IdlStruct):
        return {"type_id": ELEMENT_IDS["nested"], "capacity": 0, "string_capacity": 0, "nested": hint}
    if typing.get_origin(hint) is typing.Annotated:
        base, holder = typing.get_args(hint)[:2]
        if isinstance(holder, idl.bounded_str):
            return {"type_id": ELEMENT_IDS["bounded_string"], "capacity": 0, "string_capacity": holder.max_length,
                    "nested": None}
        if isinstance(holder, str) and holder in ELEMENT_IDS:
            return {"type_id": ELEMENT_IDS[holder], "capacity": 0, "string_capacity": 0, "nested": None}
        hint = base
    if hint in _PYTHON_TYPES:
        return {"type_id": ELEMENT_IDS[_PYTHON_TYPES[hint]], "capacity": 0, "string_capacity": 0, "nested": None}
    raise TypeError(f"no ROS 2 field type for the annotation {hint!r}")
