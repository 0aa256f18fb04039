"""Any ROS 2 interface by name, and its messages as plain data: what ros2cli does, without it.

There are no ros2cli or rosidl_runtime_py wheels, so the embedded install's
command line (``./seapup topic|service|param|interface ...``) converts
messages generically from the fields every generated class introspects
(``SLOT_TYPES`` from rosidl_parser, ``get_fields_and_field_types()``), with
no per-type code:

- :func:`interface_class` -- ``pkg/msg/Type``, ``pkg/srv/Type``,
  ``pkg/action/Type`` (or ``pkg/Type``) to the generated class;
- :func:`to_data` / :func:`fill` -- message to nested dicts/lists and back,
  every value checked against its field's type (a clear error naming the
  field, never a half-filled message);
- :func:`to_yaml` -- the YAML-like text ``ros2 topic echo`` prints;
- :func:`field_value` -- ``--field a.b`` of a message;
- :func:`definition` -- the field list ``ros2 interface show`` prints.
"""
from __future__ import annotations

import array
import importlib
import math

import numpy as np
from rosidl_parser import definition as idl

__all__ = ["InterfaceError", "interface_class", "to_data", "fill", "to_yaml", "field_value", "definition",
           "type_name"]

_INTEGER_RANGES = {
    "int8": (-2**7, 2**7 - 1), "uint8": (0, 2**8 - 1), "int16": (-2**15, 2**15 - 1), "uint16": (0, 2**16 - 1),
    "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1), "int64": (-2**63, 2**63 - 1),
    "uint64": (0, 2**64 - 1), "octet": (0, 255), "byte": (0, 255), "char": (0, 255),
}
_FLOATS = {"float", "double", "long double"}


class InterfaceError(ValueError):
    """An unknown interface, or data that does not fit it (the message names the field)."""


def interface_class(name: str):
    """The generated class of ``pkg/msg/Type`` (or ``pkg/srv/Type``, ``pkg/action/Type``, ``pkg/Type``).

    Raises
    ------
    InterfaceError
        Naming what was not found.

    Examples
    --------
    >>> interface_class("geometry_msgs/msg/Twist").__name__
    'Twist'
    """
    parts = str(name).strip().split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or not all(parts) or parts[1] not in ("msg", "srv", "action"):
        raise InterfaceError(f"{name!r} is not an interface name: use pkg/msg/Type, pkg/srv/Type or pkg/action/Type")
    package, kind, type_ = parts
    try:
        module = importlib.import_module(f"{package}.{kind}")
    except ImportError:
        raise InterfaceError(f"unknown interface package {package!r} (no {package}.{kind} module)") from None
    cls = getattr(module, type_, None)
    if cls is None or not isinstance(cls, type):
        raise InterfaceError(f"{package}/{kind} has no {type_!r}")
    return cls


def type_name(cls) -> str:
    """``pkg/msg/Type`` of a generated message class (or instance)."""
    cls = cls if isinstance(cls, type) else type(cls)
    module = cls.__module__.split(".")
    return f"{module[0]}/{module[1]}/{cls.__name__}"


def _fields(msg_or_cls):
    cls = msg_or_cls if isinstance(msg_or_cls, type) else type(msg_or_cls)
    return list(zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES))


def to_data(msg):
    """A message as nested dicts (field order kept), lists and Python scalars."""
    if hasattr(type(msg), "get_fields_and_field_types"):
        return {name: to_data(getattr(msg, name)) for name, _ in _fields(msg)}
    if isinstance(msg, np.ndarray):
        return msg.tolist()
    if isinstance(msg, (list, tuple, array.array)):
        return [to_data(v) for v in msg]
    if isinstance(msg, bytes):
        return list(msg)
    if isinstance(msg, np.generic):
        return msg.item()
    return msg


def _scalar(value, slot, where: str):
    if isinstance(slot, idl.BasicType):
        t = slot.typename
        if t == "boolean":
            if isinstance(value, bool):
                return value
            raise InterfaceError(f"{where}: expected true or false, got {value!r}")
        if t in _FLOATS:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InterfaceError(f"{where}: expected a number, got {value!r}")
            return float(value)
        lo, hi = _INTEGER_RANGES.get(t, (-math.inf, math.inf))
        if t in ("byte", "octet") and isinstance(value, (bytes, bytearray)) and len(value) == 1:
            return bytes(value)
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise InterfaceError(f"{where}: expected an integer in [{lo}, {hi}] ({t}), got {value!r}")
        return bytes([value]) if t in ("byte", "octet") else value
    if isinstance(slot, idl.AbstractGenericString):
        if not isinstance(value, str):
            raise InterfaceError(f"{where}: expected a string, got {value!r}")
        if isinstance(slot, idl.BoundedString) and len(value) > slot.maximum_size:
            raise InterfaceError(f"{where}: at most {slot.maximum_size} characters")
        return value
    if isinstance(slot, idl.NamespacedType):
        cls = interface_class("/".join([*slot.namespaces, slot.name]))
        return fill(cls(), value, where)
    raise InterfaceError(f"{where}: unsupported field type {slot!r}")


def _value(value, slot, where: str):
    if isinstance(slot, idl.AbstractNestedType):
        if not isinstance(value, (list, tuple)):
            raise InterfaceError(f"{where}: expected a list, got {value!r}")
        if isinstance(slot, idl.Array) and len(value) != slot.size:
            raise InterfaceError(f"{where}: expected exactly {slot.size} values, got {len(value)}")
        if isinstance(slot, idl.BoundedSequence) and len(value) > slot.maximum_size:
            raise InterfaceError(f"{where}: at most {slot.maximum_size} values, got {len(value)}")
        return [_scalar(v, slot.value_type, f"{where}[{i}]") for i, v in enumerate(value)]
    return _scalar(value, slot, where)


def fill(msg, data, where: str = ""):
    """Set ``msg``'s fields from ``data`` (a mapping; missing fields keep their defaults).

    Everything is converted and checked first, then assigned: on an error
    nothing of ``msg`` has changed.

    Raises
    ------
    InterfaceError
        An unknown field (the known ones are listed), or a value of the wrong type, length or range.
    """
    if data is None:
        return msg
    if not isinstance(data, dict):
        raise InterfaceError(f"{where or type_name(msg)}: expected a mapping of fields, got {data!r}")
    slots = dict(_fields(msg))
    unknown = [k for k in data if k not in slots]
    if unknown:
        raise InterfaceError(f"{where or type_name(msg)}: no field {unknown[0]!r} "
                             f"(fields: {', '.join(slots) or 'none'})")
    values = {k: _value(v, slots[k], f"{where}.{k}" if where else k) for k, v in data.items()}
    for k, v in values.items():
        setattr(msg, k, v)
    return msg


def _yaml_scalar(value) -> str:
    if isinstance(value, str):
        return "''" if value == "" else (repr(value) if any(c in value for c in ":#'\"\n") or value.strip() != value
                                          else value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value):
            return ".nan"
        if math.isinf(value):
            return ".inf" if value > 0 else "-.inf"
        return repr(value)
    return str(value)


def to_yaml(data, indent: int = 0) -> str:
    """YAML-like text as ``ros2 topic echo`` prints it (``data`` from :func:`to_data`, or a message)."""
    if hasattr(type(data), "get_fields_and_field_types"):
        data = to_data(data)
    pad = "  " * indent
    if isinstance(data, dict):
        lines = []
        for k, v in data.items():
            if isinstance(v, dict):
                lines.append(f"{pad}{k}:" + ("" if v else " {}"))
                if v:
                    lines.append(to_yaml(v, indent + 1))
            elif isinstance(v, list) and v and isinstance(v[0], dict):
                lines.append(f"{pad}{k}:")
                for item in v:
                    body = to_yaml(item, 0).splitlines() or ["{}"]
                    lines.append(f"{pad}- {body[0]}")
                    lines.extend(f"{pad}  {line}" for line in body[1:])
            elif isinstance(v, list):
                lines.append(f"{pad}{k}:" + (" []" if not v else ""))
                lines.extend(f"{pad}- {_yaml_scalar(x)}" for x in v)
            else:
                lines.append(f"{pad}{k}: {_yaml_scalar(v)}")
        return "\n".join(lines)
    return pad + _yaml_scalar(data)


def field_value(msg, path: str):
    """``msg``'s field at ``a.b.c`` (list items by index: ``a.0``) as plain data."""
    node = to_data(msg)
    for part in [p for p in str(path).split(".") if p]:
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.lstrip("-").isdigit() and -len(node) <= int(part) < len(node):
            node = node[int(part)]
        else:
            raise InterfaceError(f"no field {path!r} (at {part!r})")
    return node


_MSG_NAMES = {"boolean": "bool", "octet": "byte", "float": "float32", "double": "float64"}


def _msg_type_text(slot) -> str:
    """A field type as .msg files spell it (``float64[4]``, ``string<=10``, ``std_msgs/Header``)."""
    if isinstance(slot, idl.Array):
        return f"{_msg_type_text(slot.value_type)}[{slot.size}]"
    if isinstance(slot, idl.BoundedSequence):
        return f"{_msg_type_text(slot.value_type)}[<={slot.maximum_size}]"
    if isinstance(slot, idl.UnboundedSequence):
        return f"{_msg_type_text(slot.value_type)}[]"
    if isinstance(slot, idl.BasicType):
        return _MSG_NAMES.get(slot.typename, slot.typename)
    if isinstance(slot, idl.AbstractGenericString):
        base = "wstring" if isinstance(slot, idl.AbstractWString) else "string"
        return f"{base}<={slot.maximum_size}" if hasattr(slot, "maximum_size") else base
    if isinstance(slot, idl.NamespacedType):
        return f"{slot.namespaces[0]}/{slot.name}"
    return str(slot)


def _constants(cls) -> list[str]:
    """``TYPE NAME=VALUE`` for each constant of a message class (the thruster order of BladePitch, say):
    the values from the generated class, the types from the installed ``.msg`` file where there is one
    (else the Python value's kind)."""
    import re
    values = getattr(type(cls), f"_Metaclass_{cls.__name__}__constants", None) or {}
    if not values:
        return []
    types = {}
    module = cls.__module__.split(".")
    try:
        from ament_index_python.packages import get_package_share_directory
        path = f"{get_package_share_directory(module[0])}/{module[1]}/{cls.__name__}.msg"
        with open(path) as f:
            for line in f:
                m = re.match(r"\s*([\w/\[\]<=]+)\s+([A-Z][A-Z0-9_]*)\s*=", line)
                if m:
                    types[m.group(2)] = m.group(1)
    except (ImportError, LookupError, OSError, IndexError):
        pass
    guess = {bool: "bool", int: "int64", float: "float64", str: "string"}
    return [f"{types.get(name, guess.get(type(value), 'int64'))} {name}="
            + (repr(value) if isinstance(value, str) else str(value)) for name, value in values.items()]


def definition(cls, indent: int = 0) -> str:
    """The fields of an interface as ``ros2 interface show`` lists them (nested types expanded)."""
    cls = cls if isinstance(cls, type) else type(cls)
    if hasattr(cls, "Goal") and hasattr(cls, "Feedback"):  # an action: goal, result, feedback
        return "\n---\n".join(definition(part) for part in (cls.Goal, cls.Result, cls.Feedback))
    if hasattr(cls, "Request") and hasattr(cls, "Response"):  # a service
        return "\n---\n".join(definition(part) for part in (cls.Request, cls.Response))
    lines = ["\t" * indent + line for line in _constants(cls)]
    if lines:
        lines.append("")
    for name, slot in zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES):
        lines.append("\t" * indent + f"{_msg_type_text(slot)} {name}")
        inner = slot.value_type if isinstance(slot, idl.AbstractNestedType) else slot
        if isinstance(inner, idl.NamespacedType):
            lines.append(definition(interface_class("/".join([*inner.namespaces, inner.name])), indent + 1))
    return "\n".join(lines).strip("\n")
