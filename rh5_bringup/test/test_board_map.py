"""The board map: the packaged file is valid, and each defect of a map gives its own BoardMapError."""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from rh5_bringup.hardware.ndlcom.board_map import (
    BoardMapError,
    default_board_map_path,
    load_board_map,
    parse_board_map,
)
from rh5_bringup.hardware.ndlcom.codec import BROADCAST, RESERVED
from rh5_msgs_py.names import ACTUATOR_NAMES, LINEAR_ACTUATOR_NAMES

Document = dict[str, Any]


@pytest.fixture(scope="module")
def packaged() -> Document:
    """The packaged board_map.yaml as parsed YAML (copy before changing)."""
    return yaml.safe_load(default_board_map_path().read_text(encoding="utf-8"))


def test_packaged_map_is_valid_and_complete() -> None:
    board_map = load_board_map()
    assert tuple(b.name for b in board_map) == ACTUATOR_NAMES
    assert [b.index for b in board_map] == list(range(32))
    addresses = board_map.addresses()
    assert len(set(addresses)) == 32
    assert board_map.pc_address == 0x01
    assert not {RESERVED, BROADCAST, board_map.pc_address} & set(addresses)
    assert {b.name for b in board_map if b.kind == "linear"} == set(LINEAR_ACTUATOR_NAMES)
    assert {b.transport for b in board_map} <= {"udp", "can"}
    assert board_map.by_address[0x43].name == "LLKnee_Act1"
    assert board_map["LLKnee_Act1"].scaling.position.lsb == 1e-6
    assert len(board_map.scaling_table()) == 32


def test_packaged_ranges_hold_the_paper_numbers() -> None:
    """Strokes 195..431 mm, 291 mm/s, 5845 N; joints +-180 deg, 660 deg/s, 167 Nm must all pass the wire check."""
    for board in load_board_map():
        pos, vel, eff = board.scaling
        if board.kind == "linear":
            assert pos.low <= 0.195
            assert pos.high >= 0.431
            assert vel.high >= 0.291
            assert eff.high >= 5845
        elif board.profile == "rotary":
            assert pos.high >= 3.1416
            assert vel.high >= 11.52
            assert eff.high >= 167


def test_load_from_a_file_and_the_default_path(tmp_path: Path, packaged: Document) -> None:
    file = tmp_path / "map.yaml"
    file.write_text(yaml.safe_dump(packaged), encoding="utf-8")
    assert load_board_map(file).boards == load_board_map().boards
    assert load_board_map(str(file)).source == str(file)
    assert load_board_map("").boards == load_board_map(None).boards


def test_file_errors(tmp_path: Path) -> None:
    with pytest.raises(BoardMapError, match="cannot read the board map"):
        load_board_map(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("boards: [", encoding="utf-8")
    with pytest.raises(BoardMapError, match="not valid YAML"):
        load_board_map(bad)


def _board(doc: Document, name: str) -> dict[str, Any]:
    return next(b for b in doc["boards"] if b["name"] == name)


def _set(name: str, key: str, value: Any) -> Callable[[Document], None]:
    def change(doc: Document) -> None:
        _board(doc, name)[key] = value

    return change


DEFECTS: list[tuple[str, Callable[[Document], None], str]] = [
    ("empty", lambda d: d.clear(), "the board map: missing key.s. boards, format, pc_address, profiles"),
    ("missing key", lambda d: d.pop("pc_address"), "missing key.s. pc_address"),
    ("unknown key", lambda d: d.update(extra=1), "unknown key.s. extra"),
    ("format", lambda d: d.update(format=2), "format 2 is not supported"),
    ("pc reserved", lambda d: d.update(pc_address=0), "pc_address: address 0x00 is reserved"),
    ("pc broadcast", lambda d: d.update(pc_address=0xFF), "pc_address: address 0xff is the NDLCom broadcast id"),
    ("pc not int", lambda d: d.update(pc_address="1"), "pc_address: address '1' is not an integer"),
    ("boards not a list", lambda d: d.update(boards={}), "boards must be a list"),
    ("missing actuator", lambda d: d["boards"].pop(5), r"no board for 1 actuator\(s\): Head_Act3"),
    ("duplicate actuator", lambda d: d["boards"].append(dict(d["boards"][0])), r"\(Body_Act1\): actuator listed twice"),
    ("unknown actuator", _set("BodyYaw", "name", "BodyYawn"), "'BodyYawn' is not an actuator"),
    ("duplicate address", _set("LLKnee_Act1", "address", 0x10), "address 0x10 is already Body_Act1's"),
    ("reserved address", _set("LLKnee_Act1", "address", 0x00), r"\(LLKnee_Act1\): address 0x00 is reserved"),
    ("broadcast address", _set("LLKnee_Act1", "address", 0xFF), "address 0xff is the NDLCom broadcast id"),
    ("address beyond a byte", _set("LLKnee_Act1", "address", 0x100), "address 256 is outside 0x01..0xfe"),
    ("negative address", _set("LLKnee_Act1", "address", -3), "address -3 is outside"),
    ("bool address", _set("LLKnee_Act1", "address", True), "address True is not an integer"),
    ("pc address clash", _set("LLKnee_Act1", "address", 0x01), "address 0x01 is the PC's own"),
    ("transport", _set("LLKnee_Act1", "transport", "serial"), "transport 'serial' is not one of udp, can"),
    ("unknown profile", _set("LLKnee_Act1", "profile", "knee"), "profile 'knee' is not defined"),
    ("kind mismatch", _set("LLKnee_Act1", "profile", "rotary"), "'rotary' is rotary, but LLKnee_Act1 is a linear"),
    ("kind mismatch rotary", _set("ALElbow", "profile", "linear"), "ALElbow is a rotary actuator"),
    ("board missing key", lambda d: _board(d, "ALElbow").pop("transport"), r"\(ALElbow\): missing key.s. transport"),
    ("board unknown key", _set("ALElbow", "gear", 100), r"\(ALElbow\): unknown key.s. gear"),
    ("board not a mapping", lambda d: d["boards"].__setitem__(3, "Head_Act1"), r"boards\[3\] must be a mapping"),
    ("no profiles", lambda d: d.update(profiles={}), "profiles must be a non-empty mapping"),
    ("profile kind", lambda d: d["profiles"]["linear"].update(kind="prismatic"), "kind 'prismatic' is not one of"),
    ("profile quantity", lambda d: d["profiles"]["linear"].pop("effort"), "profiles.linear: missing key.s. effort"),
    (
        "lsb zero",
        lambda d: d["profiles"]["rotary"]["velocity"].update(lsb=0.0),
        "profiles.rotary.velocity: lsb must be a positive finite",
    ),
    ("lsb text", lambda d: d["profiles"]["rotary"]["velocity"].update(lsb="1e-6"), "lsb '1e-6' is not a number"),
    (
        "range inverted",
        lambda d: d["profiles"]["linear"]["position"].update(range=[0.5, 0.15]),
        "profiles.linear.position: range must be finite with low < high",
    ),
    ("range shape", lambda d: d["profiles"]["linear"]["position"].update(range=[0.5]), r"range \[0.5\] must be"),
    (
        "range beyond int32",
        lambda d: d["profiles"]["linear"]["effort"].update(range=[-3e6, 3e6]),
        "profiles.linear.effort: range .* does not fit int32",
    ),
]


@pytest.mark.parametrize(("defect", "change", "match"), DEFECTS, ids=[d[0] for d in DEFECTS])
def test_each_defect_gives_its_error(
    packaged: Document, defect: str, change: Callable[[Document], None], match: str
) -> None:
    document = copy.deepcopy(packaged)
    change(document)
    with pytest.raises(BoardMapError, match=match) as info:
        parse_board_map(document, "test.yaml")
    assert str(info.value).startswith("test.yaml: ")


def test_not_a_mapping_at_all() -> None:
    with pytest.raises(BoardMapError, match="the board map must be a mapping, got list"):
        parse_board_map([1, 2])


def test_board_map_error_is_a_value_error() -> None:
    assert issubclass(BoardMapError, ValueError)
