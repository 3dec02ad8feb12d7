"""Find interface types and their definition files through the ament index."""

from __future__ import annotations

import importlib
from pathlib import Path

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
from ament_index_python.resources import get_resource, get_resources

KINDS = ("msg", "srv", "action")
# Primitive type names as .msg files spell them and as the generated classes'
# get_fields_and_field_types() does (IDL names: double, float, octet ...).
PRIMITIVES = {
    "bool",
    "byte",
    "char",
    "octet",
    "float",
    "double",
    "float32",
    "float64",
    "int8",
    "uint8",
    "int16",
    "uint16",
    "int32",
    "uint32",
    "int64",
    "uint64",
    "string",
    "wstring",
    "time",
    "duration",
}


class UnknownInterfaceError(LookupError):
    """The named interface is not installed."""


def split_type(name: str, kind: str | None = None) -> tuple[str, str, str]:
    """'pkg/msg/Name' or 'pkg/Name' → (pkg, kind, Name)."""
    parts = name.strip("/").split("/")
    if len(parts) == 3 and parts[1] in KINDS:
        return parts[0], parts[1], parts[2]
    if len(parts) == 2 and parts[0] and parts[1]:
        if kind is not None:
            return parts[0], kind, parts[1]
        for candidate in KINDS:
            if interface_file(parts[0], candidate, parts[1]) is not None:
                return parts[0], candidate, parts[1]
        raise UnknownInterfaceError(f"Unknown interface '{name}'")
    raise UnknownInterfaceError(
        f"'{name}' is not an interface name; expected 'package/msg/Name' (or srv, action)"
    )


def load_type(name: str, kind: str | None = None) -> type:
    """The generated Python class for an interface name."""
    package, kind, type_name = split_type(name, kind)
    try:
        module = importlib.import_module(f"{package}.{kind}")
        return getattr(module, type_name)
    except (ImportError, AttributeError):
        raise UnknownInterfaceError(
            f"The passed {'message' if kind == 'msg' else kind} type '{name}' is invalid"
        ) from None


def interface_file(package: str, kind: str, type_name: str) -> Path | None:
    try:
        share = Path(get_package_share_directory(package))
    except (PackageNotFoundError, ValueError):
        return None
    path = share / kind / f"{type_name}.{kind}"
    return path if path.is_file() else None


def interface_text(name: str, all_comments: bool = False, no_comments: bool = False) -> str:
    """The definition as ``ros2 interface show`` prints it.

    Nested types are expanded one tab deeper; as in ros2cli, comments are shown at
    the top level only, unless ``all_comments`` (everywhere) or ``no_comments``.
    """
    package, kind, type_name = split_type(name)
    path = interface_file(package, kind, type_name)
    if path is None:
        raise UnknownInterfaceError(f"Unknown interface '{name}'")
    return "\n".join(_expand(path, package, 0, all_comments, no_comments)).rstrip()


def _expand(
    path: Path, package: str, depth: int, all_comments: bool, no_comments: bool
) -> list[str]:
    keep_comments = all_comments if depth > 0 else not no_comments
    out = []
    for raw in path.read_text().splitlines():
        line = raw if keep_comments else raw.split("#", 1)[0].rstrip()
        if not line.strip() and (depth > 0 or not keep_comments):
            continue
        out.append("\t" * depth + line)
        nested = _nested_type(raw.strip(), package)
        if nested is not None:
            nested_path = interface_file(nested[0], "msg", nested[1])
            if nested_path is not None:
                out.extend(_expand(nested_path, nested[0], depth + 1, all_comments, no_comments))
    return out


def _nested_type(line: str, package: str) -> tuple[str, str] | None:
    if not line or line.startswith("#") or line == "---":
        return None
    field_type = line.split()[0]
    if "=" in line.split("#", 1)[0] and len(line.split()) >= 2 and "=" in line.split()[1]:
        return None  # constant
    base = field_type.split("[")[0].split("<=")[0]
    if base in PRIMITIVES:
        return None
    if "/" in base:
        nested_package, nested_name = base.split("/")[0], base.split("/")[-1]
        return nested_package, nested_name
    if base == "Header":
        return "std_msgs", "Header"
    return package, base


def all_interfaces() -> dict[str, list[str]]:
    """Every installed interface by package: {'pkg': ['msg/Name', ...]}."""
    result = {}
    for package in sorted(get_resources("rosidl_interfaces")):
        content, _ = get_resource("rosidl_interfaces", package)
        names = sorted(
            {
                line.rsplit(".", 1)[0]
                for line in content.splitlines()
                if line.endswith((".msg", ".srv", ".action"))
                or (line.endswith(".idl") and not line.startswith(("msg/", "srv/", "action/")))
            }
        )
        if not names:
            names = sorted({line.rsplit(".", 1)[0] for line in content.splitlines() if line})
        result[package] = names
    return result
