"""Serialised ROS messages without message objects: a fixed CDR layout packed with :mod:`struct`.

A node that publishes many small messages every sample (the simulator: eleven
per control period) spends most of its time in Python building message
objects -- every attribute set goes through a checking property, every header
builds two more objects -- and then in converting them to C. A
:class:`Packer` instead packs a flat sequence of numbers straight into the
bytes the middleware sends (``Publisher.publish`` takes ``bytes``): the
encapsulation header and XCDR1 little-endian, the encoding ``rmw_fastrtps``
uses, with each primitive aligned to its size (at most 8) from the start of
the payload, strings as a length (NUL included) and their bytes.

The layout is derived from the message type's own description
(``SLOT_TYPES``), so it follows the ``.msg`` file. Strings must be constant
for a packer (a ``frame_id``): they are given when it is built and packed as
literal bytes, which keeps every later offset fixed. Unbounded sequences are
not supported (the packer refuses such a type when built). Each packer is
tested against rclpy's own serialiser: ``deserialize_message(pack(values))``
equals the message built field by field.
"""
from __future__ import annotations

import importlib
import struct
from typing import Sequence

__all__ = ["Packer", "Restamper", "zero_padding", "ENCAPSULATION_CDR_LE"]

#: The four bytes before the payload: CDR, little-endian, no options.
ENCAPSULATION_CDR_LE = b"\x00\x01\x00\x00"

#: rosidl basic type -> (struct code, size)
_BASIC = {"boolean": ("?", 1), "octet": ("B", 1), "uint8": ("B", 1), "int8": ("b", 1), "char": ("B", 1),
          "uint16": ("H", 2), "int16": ("h", 2), "uint32": ("I", 4), "int32": ("i", 4),
          "uint64": ("Q", 8), "int64": ("q", 8), "float": ("f", 4), "double": ("d", 8),
          "long double": ("d", 8)}


def _message_class(namespaced) -> type:
    module = importlib.import_module(".".join(namespaced.namespaces))
    return getattr(module, namespaced.name)


class Packer:
    """The bytes of a ``msg_type`` message from the flat list of its numeric fields.

    Parameters
    ----------
    msg_type : type
        A generated ROS message class (e.g. ``nav_msgs.msg.Odometry``).
    strings : dict, optional
        The value of every string field, by dotted path (``"header.frame_id"``,
        ``"child_frame_id"``, ``"transforms[0].header.frame_id"``); a string not given is empty.
    lengths : dict, optional
        A fixed length for sequence fields, by dotted path (``{"transforms": 1}`` for a
        ``tf2_msgs/TFMessage`` of one transform): packed as CDR packs any sequence (its length, then the
        elements), with the elements' fields named ``transforms[0].header.stamp.sec``, ... A sequence not
        given a length has no fixed layout (refused).

    Attributes
    ----------
    fields : tuple of str
        The numeric fields in the order :meth:`pack` takes their values: dotted
        paths, array elements as ``name[i]`` (``"pose.covariance[35]"``).
    """

    def __init__(self, msg_type: type, strings: dict[str, str] | None = None,
                 lengths: dict[str, int] | None = None):
        self.msg_type = msg_type
        strings = dict(strings or {})
        self._lengths = dict(lengths or {})
        self._segments: list = []  # bytes (constant) or (struct.Struct, number of values)
        self._format = ""
        self._count = 0
        self._offset = 0  # from the start of the payload (after the encapsulation header)
        fields: list[str] = []
        self._walk(msg_type, "", strings, fields)
        self._flush()
        if strings:
            raise ValueError(f"{msg_type.__name__} has no string field {', '.join(sorted(strings))}")
        if self._lengths:
            raise ValueError(f"{msg_type.__name__} has no sequence field {', '.join(sorted(self._lengths))}")
        self.fields = tuple(fields)
        self.size = len(ENCAPSULATION_CDR_LE) + self._offset

    # -- building ---------------------------------------------------------------
    def _align(self, size: int) -> None:
        pad = -self._offset % min(size, 8)
        self._format += "x" * pad
        self._offset += pad

    def _value(self, code: str, size: int) -> None:
        self._align(size)
        self._format += code
        self._offset += size
        self._count += 1

    def _flush(self) -> None:
        if self._format:
            self._segments.append((struct.Struct("<" + self._format), self._count))
        self._format, self._count = "", 0

    def _constant(self, text: str) -> None:
        self._align(4)
        data = text.encode() + b"\x00"
        self._flush()
        self._segments.append(struct.pack("<I", len(data)) + data)
        self._offset += 4 + len(data)

    def _walk(self, msg_type: type, prefix: str, strings: dict, fields: list) -> None:
        for slot, kind in zip(msg_type.__slots__, msg_type.SLOT_TYPES):
            name = prefix + slot.lstrip("_")
            kind_name = type(kind).__name__
            if kind_name == "BasicType":
                self._value(*_BASIC[kind.typename])
                fields.append(name)
            elif kind_name == "Array" and type(kind.value_type).__name__ == "BasicType":
                code, size = _BASIC[kind.value_type.typename]
                for i in range(kind.size):
                    self._value(code, size)
                    fields.append(f"{name}[{i}]")
            elif kind_name == "NamespacedType":
                self._walk(_message_class(kind), name + ".", strings, fields)
            elif kind_name in ("UnboundedString", "BoundedString"):
                self._constant(strings.pop(name, ""))
            elif kind_name in ("UnboundedSequence", "BoundedSequence") and name in self._lengths:
                self._sequence(kind, name, self._lengths.pop(name), strings, fields)
            else:
                raise TypeError(f"{msg_type.__name__}.{name}: {kind_name} has no fixed layout")

    def _sequence(self, kind, name: str, length: int, strings: dict, fields: list) -> None:
        if length < 0 or (kind_bound := getattr(kind, "maximum_size", None)) is not None and length > kind_bound:
            raise ValueError(f"{name}: length {length} out of range")
        self._align(4)
        self._flush()
        self._segments.append(struct.pack("<I", length))
        self._offset += 4
        value_type = kind.value_type
        for i in range(length):
            if type(value_type).__name__ == "BasicType":
                self._value(*_BASIC[value_type.typename])
                fields.append(f"{name}[{i}]")
            else:
                self._walk(_message_class(value_type), f"{name}[{i}].", strings, fields)

    # -- packing ----------------------------------------------------------------
    def pack(self, values: Sequence) -> bytes:
        """The serialised message (encapsulation header first) of ``values``, in :attr:`fields` order."""
        if len(values) != len(self.fields):
            raise ValueError(f"{self.msg_type.__name__}: {len(values)} values for {len(self.fields)} fields")
        parts = [ENCAPSULATION_CDR_LE]
        start = 0
        for segment in self._segments:
            if isinstance(segment, bytes):
                parts.append(segment)
            else:
                packer, count = segment
                parts.append(packer.pack(*values[start:start + count]))
                start += count
        return b"".join(parts)


class Restamper:
    """The bytes of a message that changes only its header's stamp (a manifest of constant topic lists).

    The message is serialised once by rclpy; :meth:`pack` writes a new stamp
    over the first eight payload bytes, where a message that begins with a
    ``std_msgs/Header`` keeps it (seconds, then nanoseconds). Any field type is
    allowed after the header, sequences included (wide strings excepted).
    rclpy's CDR writer leaves the alignment padding (after a string, before
    the next 4- or 8-byte field) as whatever the buffer held, so the same
    message would differ in bytes from one process to the next: the padding
    is zeroed (:func:`zero_padding`), as rosbags' writer does.
    """

    _STAMP = struct.Struct("<iI")

    def __init__(self, msg):
        from rclpy.serialization import serialize_message

        if not type(msg).__slots__ or type(msg).__slots__[0] != "_header":
            raise TypeError(f"{type(msg).__name__} does not begin with a header")
        data = serialize_message(msg)
        if data[:4] != ENCAPSULATION_CDR_LE:
            raise ValueError(f"not little-endian CDR: {data[:4]!r}")
        data = zero_padding(data, type(msg))
        self._tail = data[4 + self._STAMP.size:]

    def pack(self, t_ns: int) -> bytes:
        """The message stamped ``t_ns`` [ns]."""
        return ENCAPSULATION_CDR_LE + self._STAMP.pack(*divmod(int(t_ns), 1_000_000_000)) + self._tail


def zero_padding(data: bytes, msg_type: type) -> bytes:
    """``data`` (a serialised ``msg_type``, XCDR1 little-endian with its encapsulation header) with every
    alignment padding byte -- and anything after the message's last field -- set to zero.

    The walk follows CDR: each primitive aligned to its size (at most 8) from the start of the payload,
    strings and sequences as a ``uint32`` length first. A wide string has no layout here (refused).

    Raises
    ------
    TypeError
        ``msg_type`` has a wide-string field.
    ValueError
        ``data`` is shorter than the message its lengths describe.
    """
    buf = bytearray(data)
    payload = len(ENCAPSULATION_CDR_LE)

    def align(offset: int, size: int) -> int:
        end = offset + (-offset % min(size, 8))
        buf[payload + offset:payload + end] = bytes(end - offset)
        return end

    def length(offset: int) -> tuple[int, int]:
        offset = align(offset, 4)
        if payload + offset + 4 > len(buf):
            raise ValueError(f"{msg_type.__name__}: the data end inside a length at byte {offset}")
        return struct.unpack_from("<I", buf, payload + offset)[0], offset + 4

    def element(kind, offset: int) -> int:
        name = type(kind).__name__
        if name == "BasicType":
            size = _BASIC[kind.typename][1]
            return align(offset, size) + size
        if name in ("UnboundedString", "BoundedString"):
            n, offset = length(offset)
            return offset + n
        if name == "NamespacedType":
            return message(_message_class(kind), offset)
        if name == "Array":
            for _ in range(kind.size):
                offset = element(kind.value_type, offset)
            return offset
        if name in ("UnboundedSequence", "BoundedSequence"):
            n, offset = length(offset)
            for _ in range(n):
                offset = element(kind.value_type, offset)
            return offset
        raise TypeError(f"{msg_type.__name__}: {name} fields have no padding rule here")

    def message(kind: type, offset: int) -> int:
        for slot_type in kind.SLOT_TYPES:
            offset = element(slot_type, offset)
        return offset

    end = payload + message(msg_type, 0)
    if end > len(buf):
        raise ValueError(f"{msg_type.__name__}: {len(buf)} bytes, the message needs {end}")
    buf[end:] = bytes(len(buf) - end)
    return bytes(buf)
