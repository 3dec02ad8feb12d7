"""A settings dataclass as ROS parameters, the one way every DOM-BOT node declares and
reads its parameters.

Each field is one parameter of the same name (under ``prefix``, e.g. ``geometry.``),
declared with the field's default and its ``metadata["description"]``. ``read`` builds the
dataclass from the current values with an update laid over them, so the dataclass's own
checks (``__post_init__`` raising ValueError) judge an update before the node takes it.
Tuples are declared as ROS arrays and read back as tuples.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any, Generic, TypeVar

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

T = TypeVar("T")
DESCRIPTION = "description"


def described(default: Any, description: str) -> Any:
    """A dataclass field with a default and the description its parameter is declared with."""
    if isinstance(default, list | dict | set):
        raise TypeError("use a tuple for a list default (dataclass fields are shared)")
    return dataclasses.field(default=default, metadata={DESCRIPTION: description})


class DataclassParameters(Generic[T]):
    """The fields of the dataclass ``kind`` declared as parameters of ``node``."""

    def __init__(self, node: Node, kind: type[T], prefix: str = "", description: str = ""):
        """``description``: for fields without their own (e.g. "see docs/PLANNER.md")."""
        self.node, self.kind, self.prefix = node, kind, prefix
        self.fields = {prefix + f.name: f for f in dataclasses.fields(kind)}
        for name, field in self.fields.items():
            default = field.default
            if default is dataclasses.MISSING:
                raise TypeError(f"{kind.__name__}.{field.name} needs a default")
            node.declare_parameter(
                name,
                list(default) if isinstance(default, tuple) else default,
                ParameterDescriptor(description=field.metadata.get(DESCRIPTION, description)),
            )

    @property
    def names(self) -> list[str]:
        return list(self.fields)

    def owns(self, name: str) -> bool:
        return name in self.fields

    def read(self, update: Iterable[Parameter] = ()) -> T:
        """The dataclass of the current values, those in ``update`` replaced (the others'
        are ignored); raises ValueError or TypeError when the dataclass refuses them."""
        values = {name: self.node.get_parameter(name).value for name in self.fields}
        values.update({p.name: p.value for p in update if p.name in self.fields})
        return self.kind(
            **{field.name: _plain(field, values[name]) for name, field in self.fields.items()}
        )


def _plain(field: dataclasses.Field, value: Any) -> Any:
    return tuple(value) if isinstance(field.default, tuple) else value
