"""Messages ↔ plain data ↔ YAML, with rosidl_runtime_py's semantics.

rosidl_runtime_py (message_to_yaml, set_message_fields) is not installable
from PyPI, so this small equivalent walks the generated classes'
``get_fields_and_field_types()``.
"""

from __future__ import annotations

import array
from collections import OrderedDict
from typing import Any

import numpy as np
import yaml

from dombot_ros2.interfaces import PRIMITIVES, load_type


def is_message(value: Any) -> bool:
    return hasattr(type(value), "get_fields_and_field_types")


def message_to_ordereddict(message: Any) -> OrderedDict:
    return OrderedDict(
        (name, _to_plain(getattr(message, name))) for name in message.get_fields_and_field_types()
    )


def _to_plain(value: Any) -> Any:
    if is_message(value):
        return message_to_ordereddict(value)
    if isinstance(value, (list, tuple)):
        return [_to_plain(v) for v in value]
    if isinstance(value, (np.ndarray, array.array)):
        return [v.item() if hasattr(v, "item") else v for v in value]
    if isinstance(value, bytes):
        return list(value)
    if isinstance(value, np.generic):
        return value.item()
    return value


class _Dumper(yaml.SafeDumper):
    pass


_Dumper.add_representer(
    OrderedDict,
    lambda dumper, data: dumper.represent_mapping("tag:yaml.org,2002:map", data.items()),
)


def message_to_yaml(message: Any) -> str:
    """The text ``ros2 topic echo`` prints for one message (without the ``---``)."""
    return yaml.dump(
        message_to_ordereddict(message),
        Dumper=_Dumper,
        allow_unicode=True,
        width=10000,
        default_flow_style=False,
        sort_keys=False,
    )


def parse_yaml_values(text: str) -> dict:
    """Parse a command-line YAML mapping such as ``"{data: 1.5}"``; empty text is ``{}``."""
    if not text.strip():
        return {}
    try:
        values = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise ValueError(f"the values are not valid YAML: {error}") from None
    if values is None:
        return {}
    if not isinstance(values, dict):
        raise ValueError(f"the values must be a YAML mapping like '{{field: value}}', got {text!r}")
    return values


def set_message_fields(message: Any, values: dict) -> None:
    """Fill ``message`` from nested dicts/lists, converting numbers to the field types."""
    fields = message.get_fields_and_field_types()
    for name, value in values.items():
        if name not in fields:
            raise ValueError(
                f"{type(message).__name__} has no field '{name}' (fields: {', '.join(fields)})"
            )
        setattr(message, name, _field_value(getattr(message, name), fields[name], value, name))


def _field_value(current: Any, field_type: str, value: Any, name: str) -> Any:
    if is_message(current):
        if not isinstance(value, dict):
            raise ValueError(f"field '{name}' is a {field_type} and needs a mapping, got {value!r}")
        set_message_fields(current, value)
        return current
    element = _sequence_element(field_type)
    if element is not None:
        if not isinstance(value, list):
            raise ValueError(f"field '{name}' is a {field_type} and needs a list, got {value!r}")
        if element.split("<=")[0] in PRIMITIVES:
            return [_primitive(element, v, name) for v in value]
        cls = load_type(element, kind="msg")
        items = []
        for item in value:
            instance = cls()
            set_message_fields(instance, item)
            items.append(instance)
        return items
    return _primitive(field_type, value, name)


def _sequence_element(field_type: str) -> str | None:
    if field_type.startswith("sequence<"):
        return field_type[len("sequence<") :].split(",")[0].rstrip(">").strip()
    if field_type.endswith("]"):
        return field_type[: field_type.index("[")]
    return None


def _primitive(field_type: str, value: Any, name: str) -> Any:
    try:
        if field_type in ("float", "double", "float32", "float64"):
            return float(value)
        if field_type.startswith(("int", "uint")) or field_type in ("byte", "octet", "char"):
            if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
                raise TypeError
            return int(value)
        if field_type == "bool":
            if not isinstance(value, bool):
                raise TypeError
            return value
        if field_type.startswith(("string", "wstring")):
            return str(value)
    except (TypeError, ValueError):
        raise ValueError(f"field '{name}' is a {field_type}; {value!r} does not fit") from None
    return value
