"""ros2msg schema text, checked against rosbags' independent generator and the wheels' own type hashes."""

from __future__ import annotations

import json
import re
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from rh5_msgs_py import schemas
from rh5_msgs_py.interfaces import ALL_TOPICS
from rh5_msgs_py.schemas import (
    SEPARATOR,
    SUITE_MESSAGE_TYPES,
    MessageDefinitionNotFoundError,
    message_definition,
    msg_file,
)

JAZZY = get_typestore(Stores.ROS2_JAZZY)
DELIMITER = re.compile(rf"\n{SEPARATOR}\nMSG: (\S+)\n")


@pytest.fixture(autouse=True)
def _fresh_caches() -> Iterator[None]:
    """Each test sees the environment it sets up, not an earlier test's cache."""
    schemas.message_definition.cache_clear()
    schemas._msg_text.cache_clear()
    yield
    schemas.message_definition.cache_clear()
    schemas._msg_text.cache_clear()


def sections(text: str) -> dict[str, str]:
    """Split a full definition into {"" (top level) or "pkg/Type": text}, refusing duplicate sections."""
    parts = DELIMITER.split(text)
    out = {"": parts[0]}
    for name, body in zip(parts[1::2], parts[2::2], strict=True):
        assert name not in out, f"section {name} appears twice"
        out[name] = body
    return out


PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "string", "wstring"} | {
    f"{sign}int{bits}" for sign in ("", "u") for bits in (8, 16, 32, 64)
}


def normalise(text: str, package: str) -> list[str]:
    """Comments, blank lines and field defaults stripped, whitespace collapsed and same-package
    types qualified: the form rosbags renders."""
    lines = []
    for raw in text.splitlines():
        tokens = raw.split("#", 1)[0].split()
        if not tokens:
            continue
        if len(tokens) > 2 and "=" not in tokens[1]:  # "type name default": drop the default
            tokens = tokens[:2]
        base = re.split(r"[\[<]", tokens[0], maxsplit=1)[0]
        if base not in PRIMITIVES and "/" not in base:
            tokens[0] = f"{package}/{tokens[0]}"
        lines.append(" ".join(tokens))
    return lines


def short_name(type_name: str) -> str:
    """``pkg/msg/Type`` -> ``pkg/Type`` as the MSG: lines write it."""
    return type_name.replace("/msg/", "/")


def test_suite_types_cover_every_topic() -> None:
    """Every topic's type (and std_msgs/String) has a schema; no duplicates."""
    assert {t.type for t in ALL_TOPICS} | {"std_msgs/msg/String"} == set(SUITE_MESSAGE_TYPES)
    assert len(SUITE_MESSAGE_TYPES) == len(set(SUITE_MESSAGE_TYPES))


@pytest.mark.parametrize("type_name", SUITE_MESSAGE_TYPES)
def test_top_level_is_the_msg_file_and_nested_types_follow(type_name: str) -> None:
    """The text starts with the type's .msg verbatim and has one MSG: section per nested type."""
    text = message_definition(type_name)
    parts = sections(text)
    assert parts[""] == msg_file(type_name).read_text(encoding="utf-8")
    reference, _ = JAZZY.generate_msgdef(type_name, ros_version=2)
    expected = sections(reference)
    assert set(parts) == set(expected)
    if type_name not in ("std_msgs/msg/String", "std_msgs/msg/Bool"):
        assert len(parts) > 1, "every suite type but String and Bool nests std_msgs/Header or more"
    for name, body in parts.items():
        if name:
            assert body == msg_file(name).read_text(encoding="utf-8"), name
        package = (name or type_name).split("/")[0]
        assert normalise(body, package) == normalise(expected[name], package), name


@pytest.mark.parametrize("type_name", SUITE_MESSAGE_TYPES)
def test_rosbags_parses_our_text_to_the_wheels_type_hash(type_name: str) -> None:
    """rosbags parses the text, and the RIHS01 hash of what it parsed equals the hash shipped in the wheel."""
    types = get_types_from_msg(message_definition(type_name), type_name)
    assert type_name in types
    nested = {short_name(n) for n in sections(message_definition(type_name)) if n}
    assert {short_name(t) for t in types} == nested | {short_name(type_name)}
    store = get_typestore(Stores.EMPTY)
    store.register(types)
    description = json.loads(msg_file(type_name).with_suffix(".json").read_text(encoding="utf-8"))
    shipped = {h["type_name"]: h["hash_string"] for h in description["type_hashes"]}
    assert store.hash_rihs01(type_name) == shipped[type_name] == JAZZY.hash_rihs01(type_name)


def test_nested_order_is_rosbag2s() -> None:
    """Depth first, each referring file's dependencies in sorted order, separated by a newline (rosbag2)."""
    text = message_definition("geometry_msgs/msg/WrenchStamped")
    assert DELIMITER.findall(text) == [
        "geometry_msgs/Wrench",
        "geometry_msgs/Vector3",
        "std_msgs/Header",
        "builtin_interfaces/Time",
    ]
    assert f"torque\n\n{SEPARATOR}\nMSG: geometry_msgs/Vector3\n" in text
    jt = DELIMITER.findall(message_definition("trajectory_msgs/msg/JointTrajectory"))
    assert jt == [
        "std_msgs/Header",
        "builtin_interfaces/Time",
        "trajectory_msgs/JointTrajectoryPoint",
        "builtin_interfaces/Duration",
    ]


def test_unknown_and_malformed_types_raise_clearly() -> None:
    """A missing type names itself and the folders searched; a service or junk name is refused."""
    with pytest.raises(MessageDefinitionNotFoundError, match=r"'sensor_msgs/msg/NoSuchType'.*NoSuchType\.msg"):
        message_definition("sensor_msgs/msg/NoSuchType")
    with pytest.raises(MessageDefinitionNotFoundError, match="no_such_pkg"):
        message_definition("no_such_pkg/msg/Foo")
    for bad in ("std_srvs/srv/Trigger", "JointState", "sensor_msgs/msg/Joint State", ""):
        with pytest.raises(ValueError, match="not a message type name"):
            message_definition(bad)


def test_prefixes_come_from_ament_prefix_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A package found only through AMENT_PREFIX_PATH resolves, same-package names included."""
    share = tmp_path / "share" / "probe_msgs" / "msg"
    share.mkdir(parents=True)
    (share / "Outer.msg").write_text("# outer\nstd_msgs/Header header\nInner[] inner\nstring<=5 tag\nint32 X=3\n")
    (share / "Inner.msg").write_text("float64 value 1.5\n")
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path))
    text = message_definition("probe_msgs/msg/Outer")
    assert DELIMITER.findall(text) == ["probe_msgs/Inner", "std_msgs/Header", "builtin_interfaces/Time"]
    assert text.startswith("# outer\n")
    # sys.prefix stays the fallback, so std_msgs still came from the venv:
    assert msg_file("std_msgs/msg/Header").is_relative_to(sys.prefix)
    assert sections(text)["probe_msgs/Inner"] == "float64 value 1.5\n"
