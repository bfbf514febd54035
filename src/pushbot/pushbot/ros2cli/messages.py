"""The CLI's one message codec: ROS message <-> plain data <-> YAML text.

Works on any generated message (or service request/response) class through
``get_fields_and_field_types()``, so it needs no ``rosidl_runtime_py`` (not on PyPI).

- Out (``pushbot topic echo``, ``service call``'s response): :func:`message_to_dict` then
  :func:`to_yaml`. Long arrays (image data, point clouds) are replaced by a one-line summary
  so that echoing a camera topic stays readable.
- In (``pushbot topic pub``, ``service call``'s request, ``pushbot goal``):
  :func:`message_from_yaml` parses YAML as ``ros2 topic pub`` takes it (a flow mapping such as
  ``"{header: {frame_id: world}, pose: {position: {x: 0.05}}}"``; fields left out keep their
  defaults) and :func:`fill_message` sets the fields, refusing unknown fields and values of the
  wrong type with a :class:`MessageFieldError` naming the field.
"""

from __future__ import annotations

import array
import json
import math
import re
from collections.abc import Callable, Mapping
from typing import Any

import yaml

DEFAULT_MAX_ARRAY = 128
"""Arrays longer than this are summarised instead of printed in full (ros2 topic echo's
``--truncate-length`` default: a node's DiagnosticStatus key-values print in full)."""

_SUMMARY_HEAD = 8


class ArraySummary(str):
    """A string standing for a truncated array, e.g. ``<9216 x uint8, starts [0, 0, ...]>``."""


def message_to_dict(msg: Any, max_array: int = DEFAULT_MAX_ARRAY) -> dict[str, Any]:
    """Convert a ROS message instance to nested dicts, lists and scalars.

    Parameters
    ----------
    msg
        An instance of a generated message class (anything with
        ``get_fields_and_field_types()``).
    max_array
        Arrays and sequences with more elements than this become an :class:`ArraySummary`
        giving the element type, the length and the first few elements. ``0`` disables
        truncation.
    """
    return {
        field: _to_plain(getattr(msg, field), field_type, max_array)
        for field, field_type in msg.get_fields_and_field_types().items()
    }


def _element_type(field_type: str) -> str:
    """'sequence<uint8, 10>' -> 'uint8', 'float64[36]' -> 'float64'."""
    match = re.fullmatch(r"sequence<([^,>]+)(?:,\s*\d+)?>", field_type)
    if match:
        return match.group(1)
    return re.sub(r"\[\d*\]$", "", field_type)


def _to_plain(value: Any, field_type: str, max_array: int) -> Any:
    if hasattr(value, "get_fields_and_field_types"):
        return message_to_dict(value, max_array)
    if isinstance(value, (bytes, bytearray)):
        # A byte (octet) field: rclpy holds it as bytes; ros2 prints it as the string of those
        # characters (rosidl_runtime_py), e.g. DiagnosticStatus.level 0 as "\0".
        return "".join(chr(c) for c in value)
    if hasattr(value, "tolist") and not isinstance(value, (list, tuple)):
        # numpy arrays (fixed-size numeric fields) and numpy scalars
        value = value.tolist()
    if isinstance(value, (list, tuple, array.array)):
        element_type = _element_type(field_type)
        if max_array and len(value) > max_array:
            head = [_to_plain(v, element_type, max_array) for v in list(value[:_SUMMARY_HEAD])]
            shown = ", ".join(_scalar(v) if not isinstance(v, dict) else "{...}" for v in head)
            return ArraySummary(
                f"<{len(value)} x {element_type}, starts [{shown}, ...]>"
            )
        return [_to_plain(v, element_type, max_array) for v in value]
    return value


_YAML_WORDS = {"", "~", "null", "true", "false", "yes", "no", "on", "off", "y", "n"}
_YAML_SPECIAL_START = tuple('-?:,[]{}#&*!|>\'"%@`')


def _scalar(value: Any) -> str:
    """Format one scalar as a YAML plain or double-quoted scalar."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, float):
        if math.isnan(value):
            return ".nan"
        if math.isinf(value):
            return ".inf" if value > 0 else "-.inf"
        return repr(value)
    if isinstance(value, int):
        return str(value)
    text = str(value)
    if not text.isprintable():
        # Control characters as YAML escapes them (what ros2 prints: "\0", "\x02").
        return yaml.safe_dump(text, default_style='"', width=math.inf).rstrip("\n")
    if _needs_quotes(text):
        return json.dumps(text)
    return text


def _needs_quotes(text: str) -> bool:
    if text.lower() in _YAML_WORDS or text != text.strip() or text.startswith(_YAML_SPECIAL_START):
        return True
    if ": " in text or " #" in text or text.endswith(":") or "\n" in text or "\t" in text:
        return True
    try:
        float(text)
    except ValueError:
        return False
    return True


def to_yaml(data: Any, indent: int = 0) -> str:
    """Render plain data (dicts, lists, scalars) as block-style YAML text.

    Lists of scalars are written inline (``[1, 2, 3]``), lists of dicts as block sequences.
    The output parses with ``yaml.safe_load`` (:class:`ArraySummary` values load as strings).
    """
    return "\n".join(_yaml_lines(data, indent))


def _yaml_lines(data: Any, indent: int) -> list[str]:
    pad = " " * indent
    if isinstance(data, dict):
        if not data:
            return [pad + "{}"]
        lines: list[str] = []
        for key, value in data.items():
            if isinstance(value, dict) and value:
                lines.append(f"{pad}{key}:")
                lines.extend(_yaml_lines(value, indent + 2))
            elif isinstance(value, list) and any(isinstance(v, (dict, list)) for v in value):
                lines.append(f"{pad}{key}:")
                lines.extend(_yaml_lines(value, indent))
            else:
                lines.append(f"{pad}{key}: {_inline(value)}")
        return lines
    if isinstance(data, list):
        if not any(isinstance(v, (dict, list)) for v in data):
            return [pad + _inline(data)]
        lines = []
        for item in data:
            item_lines = _yaml_lines(item, 0) if isinstance(item, (dict, list)) else [
                _scalar(item)
            ]
            lines.append(f"{pad}- {item_lines[0]}")
            lines.extend(f"{pad}  {line}" for line in item_lines[1:])
        return lines
    return [pad + _scalar(data)]


def _inline(value: Any) -> str:
    if isinstance(value, dict):
        return "{}"
    if isinstance(value, list):
        return "[" + ", ".join(_scalar(v) for v in value) + "]"
    return _scalar(value)


class MessageFieldError(ValueError):
    """A YAML value does not fit the message: unknown field, wrong type, out of range."""


#: Integer field types and their ranges (the generated setters check them only with
#: ``ROS_PYTHON_CHECK_FIELDS``, so the codec does).
_INTEGER_TYPES = {
    "byte": (0, 255), "octet": (0, 255), "char": (0, 255), "uint8": (0, 255),
    "int8": (-2**7, 2**7 - 1), "int16": (-2**15, 2**15 - 1), "uint16": (0, 2**16 - 1),
    "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1), "int64": (-2**63, 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}
_FLOAT32_MAX = 3.4028234663852886e38
_FLOAT_TYPES = {"float", "double", "float32", "float64", "long double"}
#: The keywords of ``ros2 topic pub`` that take the clock, and the field types they fit.
_CLOCKED = {"now": ("builtin_interfaces/Time",), "auto": ("std_msgs/Header",)}


def message_from_yaml(message_class: type, text: str | None,
                      now: Callable[[], Any] | None = None) -> Any:
    """A new ``message_class`` instance with the fields given as YAML text.

    Parameters
    ----------
    message_class
        A generated message or service request class.
    text
        A YAML mapping of field names to values (nested messages as nested mappings, arrays
        as lists); empty or ``None`` for the default message. As with ``ros2 topic pub``, a
        ``builtin_interfaces/Time`` field may be ``now`` and a ``std_msgs/Header`` field
        ``auto`` (stamp now, empty frame), outside arrays.
    now
        Returns the current time as a ``builtin_interfaces/msg/Time`` (e.g. a node clock's
        ``now().to_msg()``); without it ``now`` and ``auto`` are refused.

    Raises
    ------
    MessageFieldError
        Text that is not YAML, not a mapping, or does not fit the message (names the field).
    """
    try:
        data = yaml.safe_load(text) if text and text.strip() else {}
    except yaml.YAMLError as exc:
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise MessageFieldError(f"the values are not valid YAML ({problem})") from None
    msg = message_class()
    fill_message(msg, {} if data is None else data, now=now)
    return msg


def zero_time() -> Any:
    """``builtin_interfaces/msg/Time`` zero: the ``now`` of a check that needs no clock."""
    from builtin_interfaces.msg import Time

    return Time()


def fill_message(msg: Any, data: Any, path: str = "",
                 now: Callable[[], Any] | None = None) -> None:
    """Set the fields of ``msg`` from ``data`` (a mapping); fields not in ``data`` are kept.

    Raises
    ------
    MessageFieldError
        ``data`` is not a mapping, names a field ``msg`` does not have, or holds a value of the
        wrong type or out of the field's range; the message names the field (``pose.position.x``).
    """
    type_name = _type_name(msg)
    if not isinstance(data, Mapping):
        where = f"field '{path.rstrip('.')}'" if path else "the message"
        raise MessageFieldError(f"{where} ({type_name}) takes a mapping of fields, got "
                                f"{_describe(data)}")
    fields = msg.get_fields_and_field_types()
    for key, value in data.items():
        name = f"{path}{key}"
        if key not in fields:
            raise MessageFieldError(f"{type_name} has no field '{name}' (its fields: "
                                    f"{', '.join(fields) or 'none'})")
        field_type = fields[key]
        current = getattr(msg, key)
        if value in ("now", "auto") and field_type in _CLOCKED.get(value, ()):
            if now is None:
                raise MessageFieldError(f"field '{name}' ({field_type}): '{value}' needs a "
                                        "clock here")
            stamp = now()
            setattr(msg, key, stamp if value == "now" else type(current)(stamp=stamp))
            continue
        if hasattr(current, "get_fields_and_field_types"):
            fill_message(current, value, f"{name}.", now)
            continue
        if _is_array(field_type):
            converted: Any = _array_value(value, field_type, name)
        else:
            converted = _scalar_value(value, field_type, name)
        try:
            setattr(msg, key, converted)
        except (AssertionError, TypeError, ValueError) as exc:
            detail = str(exc).splitlines()[0] if str(exc) else "out of range"
            raise MessageFieldError(f"field '{name}' ({field_type}): cannot take "
                                    f"{_describe(value)} ({detail})") from None


def _type_name(msg: Any) -> str:
    module = type(msg).__module__.split(".")
    return f"{module[0]}/{module[1]}/{type(msg).__name__}" if len(module) > 1 \
        else type(msg).__name__


def _describe(value: Any) -> str:
    text = repr(value)
    return f'{type(value).__name__} {text if len(text) <= 60 else text[:57] + "..."}'


def _is_array(field_type: str) -> bool:
    return field_type.startswith("sequence<") or bool(re.search(r"\[\d*\]$", field_type))


def _is_message_type(field_type: str) -> bool:
    return "/" in field_type


def _scalar_value(value: Any, field_type: str, name: str) -> Any:
    """``value`` converted for a scalar field, or :class:`MessageFieldError`."""
    if _is_message_type(field_type):
        from pushbot.ros2cli.discovery import import_message_class

        nested = import_message_class(field_type)()
        fill_message(nested, value, f"{name}.")
        return nested
    base = re.sub(r"<=\d+$", "", field_type)
    wrong = MessageFieldError(f"field '{name}' ({field_type}) cannot take {_describe(value)}")
    if base == "boolean":
        if not isinstance(value, bool):
            raise wrong
        return value
    if base in _INTEGER_TYPES:
        if isinstance(value, bool) or not isinstance(value, int):
            if base in ("char", "byte", "octet") and isinstance(value, str) and len(value) == 1:
                return ord(value) if base == "char" else value.encode("latin-1")
            raise wrong
        low, high = _INTEGER_TYPES[base]
        if not low <= value <= high:
            raise MessageFieldError(f"field '{name}' ({field_type}): {value} is out of range "
                                    f"[{low}, {high}]")
        return value.to_bytes(1, "little") if base in ("byte", "octet") else value
    if base in _FLOAT_TYPES:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise wrong
        value = float(value)
        if base in ("float", "float32") and math.isfinite(value) \
                and abs(value) > _FLOAT32_MAX:
            raise MessageFieldError(f"field '{name}' ({field_type}): {value} is out of the "
                                    "float32 range")
        return value
    if base in ("string", "wstring"):
        if isinstance(value, (dict, list)) or value is None:
            raise wrong
        # YAML reads an unquoted 1 or true as a number or a bool; a string field takes its text.
        return value if isinstance(value, str) else _scalar(value)
    raise wrong


def _array_value(value: Any, field_type: str, name: str) -> list[Any]:
    if not isinstance(value, list):
        raise MessageFieldError(f"field '{name}' ({field_type}) takes a list, got "
                                f"{_describe(value)}")
    element = _element_type(field_type)
    items = [_scalar_value(v, element, f"{name}[{i}]") for i, v in enumerate(value)]
    if element in ("byte", "octet"):
        return [b if isinstance(b, bytes) else bytes([b]) for b in items]
    return items
