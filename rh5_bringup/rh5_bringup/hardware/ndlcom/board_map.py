"""The board map: which NDLCom address, link and wire scaling each of the 32 actuators has.

``load_board_map()`` reads the packaged ``rh5_bringup/board_map.yaml`` (or a given file) and validates it whole:
every actuator of ``ACTUATOR_NAMES`` exactly once, addresses unique and usable, the kind matching
``LINEAR_ACTUATOR_NAMES``, every scaling representable. Each defect raises ``BoardMapError`` naming it.
"""

from __future__ import annotations

import importlib.resources
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Literal, NamedTuple

import yaml

from rh5_bringup.hardware.ndlcom.codec import BROADCAST, RESERVED
from rh5_bringup.hardware.ndlcom.scaling import Quantity, Scaling, ScalingTable
from rh5_msgs_py.names import ACTUATOR_NAMES, LINEAR_ACTUATOR_NAMES

__all__ = ["FORMAT", "KINDS", "TRANSPORTS", "Board", "BoardMap", "BoardMapError", "load_board_map", "parse_board_map"]

FORMAT: Final = 1
"""The board map file format this module reads (the ``format`` key)."""
TRANSPORTS: Final = ("udp", "can")
KINDS: Final = ("linear", "rotary")
QUANTITIES: Final = ("position", "velocity", "effort")

Kind = Literal["linear", "rotary"]
TransportName = Literal["udp", "can"]
Fail = Callable[[str], "BoardMapError"]


class BoardMapError(ValueError):
    """The board map file is missing, unreadable or invalid; the message names the defect."""


class Board(NamedTuple):
    """One actuator's board."""

    name: str
    """Actuator name (rh5_msgs_py.names.ACTUATOR_NAMES)."""
    index: int
    """Position in ACTUATOR_NAMES, i.e. in every actuator-space vector."""
    address: int
    """NDLCom id, 0x01..0xFE and not the PC's."""
    transport: TransportName
    kind: Kind
    """linear: m, m/s, N; rotary: rad, rad/s, Nm."""
    scaling: Scaling
    profile: str
    """The profile of the file the scaling came from."""


@dataclass(frozen=True)
class BoardMap:
    """All 32 boards in ACTUATOR_NAMES order, plus the PC's own NDLCom id."""

    pc_address: int
    boards: tuple[Board, ...]
    source: str = "<memory>"
    by_name: dict[str, Board] = field(init=False, repr=False, compare=False)
    by_address: dict[int, Board] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "by_name", {b.name: b for b in self.boards})
        object.__setattr__(self, "by_address", {b.address: b for b in self.boards})

    def __iter__(self) -> Iterator[Board]:
        return iter(self.boards)

    def __len__(self) -> int:
        return len(self.boards)

    def __getitem__(self, name: str) -> Board:
        return self.by_name[name]

    def addresses(self) -> tuple[int, ...]:
        """Board addresses in ACTUATOR_NAMES order."""
        return tuple(b.address for b in self.boards)

    def scaling_table(self) -> ScalingTable:
        """The scalings as arrays in ACTUATOR_NAMES order (for the batch payload codecs)."""
        return ScalingTable([b.scaling for b in self.boards], [b.name for b in self.boards])


def default_board_map_path() -> Path:
    """The packaged board_map.yaml."""
    return Path(str(importlib.resources.files("rh5_bringup.hardware").joinpath("board_map.yaml")))


def load_board_map(path: str | Path | None = None) -> BoardMap:
    """Read and validate a board map file; ``None`` (or "") reads the packaged one.

    :raises BoardMapError: the file cannot be read or parsed, or the map is invalid.
    """
    file = Path(path) if path else default_board_map_path()
    try:
        document = yaml.safe_load(file.read_text(encoding="utf-8"))
    except OSError as error:
        raise BoardMapError(f"{file}: cannot read the board map: {error.strerror or error}") from error
    except yaml.YAMLError as error:
        raise BoardMapError(f"{file}: not valid YAML: {error}") from error
    return parse_board_map(document, str(file))


def parse_board_map(document: Any, source: str = "<memory>") -> BoardMap:
    """Validate a board map given as parsed YAML (a mapping) and build it.

    :raises BoardMapError: with ``source`` and the offending entry in the message.
    """

    def fail(message: str) -> BoardMapError:
        return BoardMapError(f"{source}: {message}")

    if not isinstance(document, Mapping):
        raise fail(f"the board map must be a mapping, got {type(document).__name__}")
    _check_keys(document, {"format", "pc_address", "profiles", "boards"}, "the board map", fail)
    if document["format"] != FORMAT:
        raise fail(f"format {document['format']!r} is not supported (this reader reads format {FORMAT})")
    pc_address = _address(document["pc_address"], "pc_address", fail)
    profiles = _profiles(document["profiles"], fail)

    entries = document["boards"]
    if not isinstance(entries, list):
        raise fail(f"boards must be a list, got {type(entries).__name__}")
    boards: dict[str, Board] = {}
    owner_of_address: dict[int, str] = {}
    for position, entry in enumerate(entries):
        where = f"boards[{position}]"
        if not isinstance(entry, Mapping):
            raise fail(f"{where} must be a mapping, got {type(entry).__name__}")
        name = entry.get("name")
        if isinstance(name, str):
            where = f"{where} ({name})"
        _check_keys(entry, {"name", "address", "transport", "profile"}, where, fail)
        if name not in ACTUATOR_NAMES:
            raise fail(f"{where}: {name!r} is not an actuator of rh5_msgs_py.names.ACTUATOR_NAMES")
        if name in boards:
            raise fail(f"{where}: actuator listed twice")
        address = _address(entry["address"], where, fail)
        if address == pc_address:
            raise fail(f"{where}: address 0x{address:02x} is the PC's own (pc_address)")
        if address in owner_of_address:
            raise fail(f"{where}: address 0x{address:02x} is already {owner_of_address[address]}'s")
        transport = entry["transport"]
        if transport not in TRANSPORTS:
            raise fail(f"{where}: transport {transport!r} is not one of {', '.join(TRANSPORTS)}")
        profile = entry["profile"]
        if profile not in profiles:
            raise fail(f"{where}: profile {profile!r} is not defined under profiles")
        kind, scaling = profiles[profile]
        expected = "linear" if name in LINEAR_ACTUATOR_NAMES else "rotary"
        if kind != expected:
            raise fail(f"{where}: profile {profile!r} is {kind}, but {name} is a {expected} actuator")
        boards[name] = Board(name, ACTUATOR_NAMES.index(name), address, transport, kind, scaling, profile)
        owner_of_address[address] = name

    missing = [name for name in ACTUATOR_NAMES if name not in boards]
    if missing:
        raise fail(f"no board for {len(missing)} actuator(s): {', '.join(missing)}")
    return BoardMap(pc_address, tuple(boards[name] for name in ACTUATOR_NAMES), source)


# --------------------------------------------------------------------------------------------------- helpers


def _check_keys(entry: Mapping[str, Any], keys: set[str], where: str, fail: Fail) -> None:
    missing, unknown = keys - set(entry), set(entry) - keys
    if missing:
        raise fail(f"{where}: missing key(s) {', '.join(sorted(missing))}")
    if unknown:
        raise fail(f"{where}: unknown key(s) {', '.join(sorted(map(str, unknown)))}")


def _address(value: Any, where: str, fail: Fail) -> int:
    if not isinstance(value, int) or isinstance(value, bool):
        raise fail(f"{where}: address {value!r} is not an integer")
    if value == RESERVED:
        raise fail(f"{where}: address 0x00 is reserved by NDLCom")
    if value == BROADCAST:
        raise fail(f"{where}: address 0xff is the NDLCom broadcast id")
    if not 0 < value < BROADCAST:
        raise fail(f"{where}: address {value} is outside 0x01..0xfe")
    return value


def _profiles(document: Any, fail: Fail) -> dict[str, tuple[Kind, Scaling]]:
    if not isinstance(document, Mapping) or not document:
        raise fail("profiles must be a non-empty mapping of profile name to scaling")
    profiles: dict[str, tuple[Kind, Scaling]] = {}
    for name, profile in document.items():
        where = f"profiles.{name}"
        if not isinstance(profile, Mapping):
            raise fail(f"{where} must be a mapping, got {type(profile).__name__}")
        _check_keys(profile, {"kind", *QUANTITIES}, where, fail)
        if profile["kind"] not in KINDS:
            raise fail(f"{where}: kind {profile['kind']!r} is not one of {', '.join(KINDS)}")
        quantities = [_quantity(profile[q], f"{where}.{q}", fail) for q in QUANTITIES]
        profiles[str(name)] = (profile["kind"], Scaling(*quantities))
    return profiles


def _quantity(document: Any, where: str, fail: Fail) -> Quantity:
    if not isinstance(document, Mapping):
        raise fail(f"{where} must be a mapping with lsb and range")
    _check_keys(document, {"lsb", "range"}, where, fail)
    lsb, bounds = document["lsb"], document["range"]
    if not isinstance(lsb, int | float) or isinstance(lsb, bool):
        raise fail(f"{where}: lsb {lsb!r} is not a number")
    if (
        not isinstance(bounds, list)
        or len(bounds) != 2
        or not all(isinstance(b, int | float) and not isinstance(b, bool) for b in bounds)
    ):
        raise fail(f"{where}: range {bounds!r} must be [low, high]")
    try:
        return Quantity(float(lsb), float(bounds[0]), float(bounds[1]))
    except ValueError as error:
        raise fail(f"{where}: {error}") from None
