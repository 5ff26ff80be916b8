"""``ros2msg`` schema text of the suite's message types, as rosbag2 writes it into MCAP files.

The format is rosbag2's ``LocalMessageDefinitionSource::get_full_text`` (rosbag2_cpp, Iron and
later): the type's own ``.msg`` file verbatim, then for every nested type, each once, depth first
and in sorted order of the names as written in the referring file, ``"\\n"``, a line of 80 ``=``,
a line ``MSG: pkg/Type`` and that type's ``.msg`` file verbatim. The ``.msg`` sources are read
from ``<prefix>/share/<pkg>/msg/`` of the AMENT_PREFIX_PATH entries, then ``sys.prefix``.
"""

from __future__ import annotations

import os
import re
import sys
from functools import cache
from pathlib import Path
from typing import Final

from rh5_msgs_py.interfaces import ALL_TOPICS

__all__ = [
    "SEPARATOR",
    "SUITE_MESSAGE_TYPES",
    "MessageDefinitionNotFoundError",
    "message_definition",
    "msg_dependencies",
    "msg_file",
]

SEPARATOR: Final = "=" * 80
"""The line that precedes every nested definition (followed by ``MSG: pkg/Type``)."""

SUITE_MESSAGE_TYPES: Final[tuple[str, ...]] = tuple(sorted({t.type for t in ALL_TOPICS} | {"std_msgs/msg/String"}))
"""Every message type the suite publishes (``pkg/msg/Type``), sorted: what the recorder needs schemas for."""

# Same primitive set as rosbag2 (plus wstring, which rosbag2 would wrongly treat as a nested type).
_PRIMITIVES: Final = frozenset(
    {
        "bool",
        "byte",
        "char",
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
    }
)
_NAME: Final = r"[A-Za-z][A-Za-z0-9_]*"
_TYPE_RE: Final = re.compile(rf"^({_NAME})/(?:(msg)/)?({_NAME})$")
# First token of a field or constant line, as rosbag2's MSG_FIELD_TYPE_REGEX takes it: the type with an
# optional array suffix, then whitespace. Bounded strings (``string<=5``) never match, like in rosbag2.
_FIELD_TYPE_RE: Final = re.compile(r"^\s*([A-Za-z0-9_/]+)(?:\[[^\]]*\])?\s+")


class MessageDefinitionNotFoundError(LookupError):
    """No ``.msg`` file for a message type in any share directory searched."""


def _prefixes() -> list[Path]:
    """Install prefixes to search, in order: AMENT_PREFIX_PATH entries, then ``sys.prefix``."""
    entries = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    fallback = Path(sys.prefix)
    return entries if fallback in entries else [*entries, fallback]


def _split_type(type_name: str) -> tuple[str, str]:
    """``pkg/msg/Type`` or ``pkg/Type`` -> (pkg, Type); ValueError for anything else (srv, action, junk)."""
    match = _TYPE_RE.match(type_name)
    if match is None:
        msg = f"not a message type name: {type_name!r} (expected 'pkg/msg/Type' or 'pkg/Type')"
        raise ValueError(msg)
    return match.group(1), match.group(3)


def msg_file(type_name: str) -> Path:
    """Path of the ``.msg`` source of ``type_name`` (``pkg/msg/Type`` or ``pkg/Type``)."""
    pkg, name = _split_type(type_name)
    searched = []
    for prefix in _prefixes():
        path = prefix / "share" / pkg / "msg" / f"{name}.msg"
        if path.is_file():
            return path
        searched.append(str(path.parent))
    msg = f"no message definition for {type_name!r}: {name}.msg not found in {', '.join(searched)}"
    raise MessageDefinitionNotFoundError(msg)


@cache
def _msg_text(type_name: str) -> str:
    """The ``.msg`` file of a type, verbatim (cached per ``pkg/Type``)."""
    return msg_file(type_name).read_text(encoding="utf-8")


def msg_dependencies(text: str, package: str) -> list[str]:
    """Nested types (``pkg/Type``) referenced by one ``.msg`` text, sorted and unique as rosbag2 keeps them."""
    deps: set[str] = set()
    for line in text.splitlines():
        match = _FIELD_TYPE_RE.match(line)
        if match is None or match.group(1) in _PRIMITIVES:
            continue
        type_name = match.group(1)
        deps.add(type_name if "/" in type_name else f"{package}/{type_name}")
    return sorted(deps)


@cache
def message_definition(type_name: str) -> str:
    """Full ``ros2msg`` schema text of ``type_name`` (e.g. ``sensor_msgs/msg/JointState``), cached.

    Raises ValueError for a malformed name and MessageDefinitionNotFoundError when a ``.msg`` is missing.
    """
    _split_type(type_name)
    seen: set[str] = set()
    max_depth = 50

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            msg = f"nesting too deep while resolving {type_name!r} (cycle at {name!r}?)"
            raise RecursionError(msg)
        text = _msg_text(name)
        parts = [text]
        for dep in msg_dependencies(text, _split_type(name)[0]):
            if dep not in seen:
                seen.add(dep)
                parts.append(f"\n{SEPARATOR}\nMSG: {dep}\n{append(dep, depth - 1)}")
        return "".join(parts)

    return append(type_name, max_depth)
