"""Generic ROS message -> plain data -> YAML-ish text, for ``pushbot topic echo``.

Works on any generated message class through ``get_fields_and_field_types()``, so it needs no
``rosidl_runtime_py``. Long arrays (image data, point clouds) are replaced by a one-line
summary so that echoing a camera topic stays readable.
"""

from __future__ import annotations

import array
import json
import math
import re
from typing import Any

DEFAULT_MAX_ARRAY = 32
"""Arrays longer than this are summarised instead of printed in full."""

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
    match = re.fullmatch(r'sequence<([^,>]+)(?:,\s*\d+)?>', field_type)
    if match:
        return match.group(1)
    return re.sub(r'\[\d*\]$', '', field_type)


def _to_plain(value: Any, field_type: str, max_array: int) -> Any:
    if hasattr(value, 'get_fields_and_field_types'):
        return message_to_dict(value, max_array)
    if isinstance(value, (bytes, bytearray)):
        value = list(value)
    elif hasattr(value, 'tolist') and not isinstance(value, (list, tuple)):
        # numpy arrays (fixed-size numeric fields) and numpy scalars
        value = value.tolist()
    if isinstance(value, (list, tuple, array.array)):
        element_type = _element_type(field_type)
        if max_array and len(value) > max_array:
            head = [_to_plain(v, element_type, max_array) for v in list(value[:_SUMMARY_HEAD])]
            shown = ', '.join(_scalar(v) if not isinstance(v, dict) else '{...}' for v in head)
            return ArraySummary(
                f'<{len(value)} x {element_type}, starts [{shown}, ...]>'
            )
        return [_to_plain(v, element_type, max_array) for v in value]
    return value


_YAML_WORDS = {'', '~', 'null', 'true', 'false', 'yes', 'no', 'on', 'off', 'y', 'n'}
_YAML_SPECIAL_START = tuple('-?:,[]{}#&*!|>\'"%@`')


def _scalar(value: Any) -> str:
    """Format one scalar as a YAML plain or double-quoted scalar."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if value is None:
        return 'null'
    if isinstance(value, float):
        if math.isnan(value):
            return '.nan'
        if math.isinf(value):
            return '.inf' if value > 0 else '-.inf'
        return repr(value)
    if isinstance(value, int):
        return str(value)
    text = str(value)
    if _needs_quotes(text):
        return json.dumps(text)
    return text


def _needs_quotes(text: str) -> bool:
    if text.lower() in _YAML_WORDS or text != text.strip() or text.startswith(_YAML_SPECIAL_START):
        return True
    if ': ' in text or ' #' in text or text.endswith(':') or '\n' in text or '\t' in text:
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
    return '\n'.join(_yaml_lines(data, indent))


def _yaml_lines(data: Any, indent: int) -> list[str]:
    pad = ' ' * indent
    if isinstance(data, dict):
        if not data:
            return [pad + '{}']
        lines: list[str] = []
        for key, value in data.items():
            if isinstance(value, dict) and value:
                lines.append(f'{pad}{key}:')
                lines.extend(_yaml_lines(value, indent + 2))
            elif isinstance(value, list) and any(isinstance(v, (dict, list)) for v in value):
                lines.append(f'{pad}{key}:')
                lines.extend(_yaml_lines(value, indent))
            else:
                lines.append(f'{pad}{key}: {_inline(value)}')
        return lines
    if isinstance(data, list):
        if not any(isinstance(v, (dict, list)) for v in data):
            return [pad + _inline(data)]
        lines = []
        for item in data:
            item_lines = _yaml_lines(item, 0) if isinstance(item, (dict, list)) else [
                _scalar(item)
            ]
            lines.append(f'{pad}- {item_lines[0]}')
            lines.extend(f'{pad}  {line}' for line in item_lines[1:])
        return lines
    return [pad + _scalar(data)]


def _inline(value: Any) -> str:
    if isinstance(value, dict):
        return '{}'
    if isinstance(value, list):
        return '[' + ', '.join(_scalar(v) for v in value) + ']'
    return _scalar(value)
