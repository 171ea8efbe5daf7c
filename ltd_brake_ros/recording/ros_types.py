"""ROS message types as a recording needs them: names, ``ros2msg`` definitions, type hashes.

The types the plant records ship with the package (``message_definitions.json``); others are
read from the installed message packages (``share/<pkg>/msg/*.msg`` and ``*.json``), with the
message classes only to find nested types; nothing here needs a running ROS graph.
"""
from __future__ import annotations

import importlib
import json
import os
import sys
from pathlib import Path
from typing import Iterator

__all__ = ["MessageTypeError", "split_type", "message_class", "type_name", "message_definition",
           "type_description_hash"]


class MessageTypeError(LookupError, ValueError):
    """A recorded message type that names no installed ROS message (a ``ValueError`` too:
    the name comes from a file)."""


def split_type(msg_type: str) -> tuple[str, str, str]:
    """Package, namespace and name of a message type.

    Parameters
    ----------
    msg_type : str
        ``pkg/msg/Type`` (or ``pkg/Type``).

    Returns
    -------
    tuple of str
        ``(pkg, "msg", "Type")``.

    Raises
    ------
    ValueError
        Not a type name.
    """
    parts = msg_type.split("/")
    if len(parts) == 2:
        return parts[0], "msg", parts[1]
    if len(parts) == 3 and all(parts):
        return parts[0], parts[1], parts[2]
    raise ValueError(f"message type must look like 'pkg/msg/Type', got {msg_type!r}")


def message_class(msg_type: str):
    """The installed message class of a type name.

    Parameters
    ----------
    msg_type : str
        ``pkg/msg/Type``.

    Returns
    -------
    type

    Raises
    ------
    MessageTypeError
        Not a message type name, or its package is not installed.
    """
    pkg, ns, name = split_type(msg_type)
    if not (pkg.isidentifier() and ns in ("msg", "action", "srv") and name.isidentifier()):
        raise MessageTypeError(f"{msg_type!r} is not a ROS message type name")
    try:
        cls = getattr(importlib.import_module(f"{pkg}.{ns}"), name)
    except (ImportError, AttributeError) as exc:
        raise MessageTypeError(f"message type {msg_type} is not installed ({exc})") from None
    if not hasattr(cls, "SLOT_TYPES"):
        raise MessageTypeError(f"{msg_type} is not a ROS message class")
    return cls


def type_name(msg) -> str:
    """``pkg/msg/Type`` of a message instance or class (``std_msgs/msg/Bool``).

    Parameters
    ----------
    msg : message or message class

    Returns
    -------
    str
    """
    cls = msg if isinstance(msg, type) else type(msg)
    parts = cls.__module__.split(".")
    return f"{parts[0]}/{parts[1]}/{cls.__name__}"


def _share_dirs(pkg: str) -> Iterator[Path]:
    """Candidate ``share/<pkg>`` directories, most authoritative first."""
    if os.environ.get("AMENT_PREFIX_PATH"):
        try:
            from ament_index_python.packages import get_package_share_directory

            yield Path(get_package_share_directory(pkg))
        except Exception:  # noqa: BLE001 - package not registered in the index
            pass
    # Wheels and ROS installs both put share/ under the prefix that holds the Python package.
    try:
        module = importlib.import_module(pkg)
        for parent in Path(module.__file__).resolve().parents:
            yield parent / "share" / pkg
    except Exception:  # noqa: BLE001 - not importable: fall through to sys.prefix
        pass
    yield Path(sys.prefix) / "share" / pkg


def _interface_file(msg_type: str, suffix: str) -> Path:
    pkg, ns, name = split_type(msg_type)
    for share in _share_dirs(pkg):
        path = share / ns / f"{name}{suffix}"
        if path.is_file():
            return path
    raise LookupError(f"cannot find {pkg}/{ns}/{name}{suffix} in any installed share/{pkg}")


def _nested_types(msg_type: str) -> list[str]:
    """Message types used by the fields of ``msg_type`` as ``pkg/Type``, sorted."""
    from rosidl_parser.definition import AbstractNestedType, NamespacedType

    deps = set()
    for slot in message_class(msg_type).SLOT_TYPES:
        base = slot.value_type if isinstance(slot, AbstractNestedType) else slot
        if isinstance(base, NamespacedType):
            deps.add(f"{base.namespaces[0]}/{base.name}")
    return sorted(deps)


#: The definitions and type hashes of the types the plant records, as the ROS 2 Jazzy message
#: packages give them (``message_definitions.json`` beside this module, byte for byte: a test
#: compares them with the installed packages), so that recording needs no ROS install.
_SHIPPED_FILE = Path(__file__).with_name("message_definitions.json")
_SHIPPED: dict | None = None


def _shipped(msg_type: str) -> dict | None:
    """The shipped definition and hash of ``msg_type`` (``pkg/msg/Type``), or None."""
    global _SHIPPED
    if _SHIPPED is None:
        try:
            _SHIPPED = json.loads(_SHIPPED_FILE.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            _SHIPPED = {}
    pkg, ns, name = split_type(msg_type)
    return _SHIPPED.get(f"{pkg}/{ns}/{name}")


def message_definition(msg_type: str) -> str:
    """Full ``ros2msg`` schema text of a message type, as rosbag2 stores it in MCAP.

    The type's ``.msg`` file, then every nested type once (depth first, each level in sorted
    order), each preceded by a line of 80 ``=`` and ``MSG: pkg/Type``. The text is read from
    the installed message packages; nested types come from the message class's field types.

    Parameters
    ----------
    msg_type : str
        Full type name, e.g. ``std_msgs/msg/Float64MultiArray``.

    Returns
    -------
    str
    """
    shipped = _shipped(msg_type)
    if shipped is not None:
        return shipped["definition"]
    return installed_definition(msg_type)


def installed_definition(msg_type: str) -> str:
    """:func:`message_definition` read from the installed message packages (needs ROS).

    Parameters
    ----------
    msg_type : str

    Returns
    -------
    str
    """
    seen: set[str] = set()

    def expand(name: str) -> str:
        text = _interface_file(name, ".msg").read_text()
        for dep in _nested_types(name):
            if dep not in seen:
                seen.add(dep)
                text += "\n" + "=" * 80 + f"\nMSG: {dep}\n" + expand(dep)
        return text

    return expand(msg_type)


def type_description_hash(msg_type: str) -> str:
    """REP-2011 type hash (``RIHS01_...``) from the installed type description, or ``""``.

    Parameters
    ----------
    msg_type : str

    Returns
    -------
    str
    """
    shipped = _shipped(msg_type)
    if shipped is not None:
        return shipped["type_description_hash"]
    return installed_type_hash(msg_type)


def installed_type_hash(msg_type: str) -> str:
    """:func:`type_description_hash` read from the installed type description, or ``""``."""
    try:
        desc = json.loads(_interface_file(msg_type, ".json").read_text())
    except (LookupError, ValueError, OSError):
        return ""
    pkg, ns, name = split_type(msg_type)
    full = f"{pkg}/{ns}/{name}"
    return next((h["hash_string"] for h in desc.get("type_hashes", ())
                 if h.get("type_name") == full), "")
