"""The versioned RH5 trajectory file (``*.rh5traj``): what the planner writes and the planner node loads.

Container: a zip in numpy's ``.npz`` layout (one ``<name>.npy`` per array, deflate-compressed),
plus ``header.json`` (format, version, joint names, motion spec, model hash, solver log) and
``sha256.txt`` (a SHA-256 over the header and every array). Why: ``np.load`` and ``unzip`` open
it with no RH5 code (``unzip -p f.rh5traj header.json`` shows the header), the per-member CRC-32
and the zip's end record tell corruption and truncation apart, the checksum covers the whole
content, ``allow_pickle=False`` keeps loading safe, and fixed member timestamps make equal data
give byte-identical files. No ROS import here: offline tools and notebooks can use it.
Layout, units and version policy: docs/trajectory_format.md.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import tempfile
import zipfile
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rh5_msgs_py.array_types import BoolArray, FloatArray
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "NQ",
    "NV",
    "NX",
    "SUFFIX",
    "SUPPORTED_VERSIONS",
    "ModelHashMismatchError",
    "TrajectoryContentError",
    "TrajectoryCorruptedError",
    "TrajectoryData",
    "TrajectoryFileError",
    "TrajectoryTruncatedError",
    "TrajectoryVersionError",
    "checksum",
    "encode_trajectory",
    "load_trajectory",
    "save_trajectory",
]

FORMAT_NAME: Final = "rh5_trajectory"
FORMAT_VERSION: Final = 1
SUPPORTED_VERSIONS: Final = (1,)
SUFFIX: Final = ".rh5traj"

NQ: Final = 7 + NUM_JOINTS
"""Configuration size: base position xyz [m], base quaternion xyzw, then the joints [rad] in JOINT_NAMES order."""
NV: Final = 6 + NUM_JOINTS
"""Velocity size: base twist (linear xyz [m/s], angular xyz [rad/s]), then joint velocities [rad/s]."""
NX: Final = NQ + NV

QUATERNION_TOLERANCE: Final = 1e-3
"""Largest accepted deviation of a base quaternion norm from 1."""

ARRAY_NAMES: Final = ("times", "states", "controls", "contact_wrenches", "contact_phases", "cop")
"""Array entries in checksum order."""
HEADER_ENTRY: Final = "header.json"
CHECKSUM_ENTRY: Final = "sha256.txt"
CHECKSUM_DOMAIN: Final = b"rh5traj-sha256-v1\0"

_ZIP_MAGIC: Final = b"PK\x03\x04"
_ZIP_END_MAGIC: Final = b"PK\x05\x06"
_ZIP_END_SEARCH: Final = 22 + 0xFFFF  # end record + the longest zip comment
_ZIP_DATE: Final = (1980, 1, 1, 0, 0, 0)


class TrajectoryFileError(ValueError):
    """A trajectory file (or trajectory data) that cannot be used; the message names the file and the problem."""


class TrajectoryCorruptedError(TrajectoryFileError):
    """Bytes changed: not a zip, a bad CRC, an unreadable entry or a checksum mismatch."""


class TrajectoryTruncatedError(TrajectoryFileError):
    """The file ends early (empty, or the zip end record is missing): typically an interrupted copy."""


class TrajectoryVersionError(TrajectoryFileError):
    """The file's format version is not one this reader supports."""


class TrajectoryContentError(TrajectoryFileError):
    """Intact file or in-memory data with wrong content: shapes, joint names, values, missing entries."""


class ModelHashMismatchError(TrajectoryFileError):
    """The trajectory was planned for a different robot model than the one in use."""


def _float_array(name: str, value: ArrayLike, shape: tuple[int, ...], *, allow_nan: bool = False) -> FloatArray:
    try:
        arr = np.array(value, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as err:
        msg = f"{name} is not a float array: {err}"
        raise TrajectoryContentError(msg) from None
    if arr.shape != shape:
        msg = f"{name} must have shape {shape}, got {arr.shape}"
        raise TrajectoryContentError(msg)
    bad = np.isinf(arr) if allow_nan else ~np.isfinite(arr)
    if bad.any():
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        msg = f"{name} has a non-finite value {arr[where]} at index {where}"
        raise TrajectoryContentError(msg)
    arr.setflags(write=False)
    return arr


def _json_mapping(name: str, value: Mapping[str, Any]) -> dict[str, Any]:
    """Deep copy of a JSON-able mapping as the JSON round trip gives it back (tuples become lists)."""
    if not isinstance(value, Mapping):
        msg = f"{name} must be a mapping, got {type(value).__name__}"
        raise TrajectoryContentError(msg)
    try:
        return json.loads(json.dumps(value))  # type: ignore[no-any-return]
    except (TypeError, ValueError) as err:
        msg = f"{name} is not JSON-able: {err}"
        raise TrajectoryContentError(msg) from None


@dataclass(frozen=True, eq=False)
class TrajectoryData:
    """A planned whole-body trajectory: N knots of states X*, controls U*, contact wrenches, phases and CoPs.

    Arrays are copied and made read-only on construction (a safe snapshot to hand between threads);
    every shape and value is checked, raising TrajectoryContentError.
    """

    times: FloatArray
    """(N,) knot times [s], strictly increasing."""
    states: FloatArray
    """(N, NX) X*: q (NQ: base xyz, quaternion xyzw, joints) then v (NV: base twist, joint velocities)."""
    controls: FloatArray
    """(N-1, 32) or (N, 32) U*: joint torques [Nm] in JOINT_NAMES order (row k acts from knot k to k+1)."""
    contact_wrenches: FloatArray
    """(N, 2, 6) F_ext* per foot (left, right): force xyz [N], torque xyz [Nm] (frames: docs/trajectory_format.md)."""
    contact_phases: BoolArray
    """(N, 2) True where the foot (left, right) is in contact."""
    cop: FloatArray
    """(N, 2, 2) centre of pressure x, y [m] per foot in its sole frame; NaN where not in contact."""
    motion: Mapping[str, Any]
    """The motion spec, JSON-able, with at least ``name``; conventionally also ``parameters``."""
    model_hash: str
    """Hash of the robot model the trajectory was planned for (see load_trajectory's expected_model_hash)."""
    solver_log: Mapping[str, Any] = field(default_factory=dict)
    """JSON-able solver record: iterations, cost, stop criterion, time, ..."""
    joint_names: tuple[str, ...] = JOINT_NAMES
    """Must equal names.JOINT_NAMES: stored so a file states its own column order."""

    def __post_init__(self) -> None:
        names = tuple(self.joint_names)
        if names != JOINT_NAMES:
            missing = [n for n in JOINT_NAMES if n not in names]
            unknown = [n for n in names if n not in JOINT_NAMES]
            detail = f"missing {missing}, unknown {unknown}" if missing or unknown else "same names, other order"
            msg = f"joint names differ from names.JOINT_NAMES ({detail})"
            raise TrajectoryContentError(msg)
        times = np.array(self.times, dtype=np.float64, copy=True)
        if times.ndim != 1 or times.size == 0:
            msg = f"times must have shape (N,) with N >= 1, got {times.shape}"
            raise TrajectoryContentError(msg)
        n = times.size
        times = _float_array("times", times, (n,))
        steps = np.flatnonzero(np.diff(times) <= 0)
        if steps.size:
            i = int(steps[0]) + 1
            msg = f"times must increase strictly: times[{i}] = {times[i]} <= times[{i - 1}] = {times[i - 1]}"
            raise TrajectoryContentError(msg)
        states = _float_array("states", self.states, (n, NX))
        norms = np.linalg.norm(states[:, 3:7], axis=1)
        off = np.flatnonzero(np.abs(norms - 1.0) > QUATERNION_TOLERANCE)
        if off.size:
            i = int(off[0])
            msg = f"states[{i}, 3:7] (base quaternion xyzw) has norm {norms[i]:.6g}, not 1"
            raise TrajectoryContentError(msg)
        controls = np.asarray(self.controls)
        n_controls = n - 1 if controls.ndim == 2 and controls.shape[0] == n - 1 else n
        controls = _float_array(f"controls (N-1 or N = {n - 1} or {n} rows)", controls, (n_controls, NUM_JOINTS))
        wrenches = _float_array("contact_wrenches", self.contact_wrenches, (n, 2, 6))
        cop = _float_array("cop", self.cop, (n, 2, 2), allow_nan=True)
        phases = np.array(self.contact_phases, copy=True)
        if phases.shape != (n, 2):
            msg = f"contact_phases must have shape {(n, 2)}, got {phases.shape}"
            raise TrajectoryContentError(msg)
        if phases.dtype != np.bool_:
            if not np.isin(phases, (0, 1)).all():
                msg = f"contact_phases must be bool (or 0/1), got dtype {phases.dtype} with other values"
                raise TrajectoryContentError(msg)
            phases = phases.astype(np.bool_)
        phases.setflags(write=False)
        motion = _json_mapping("motion", self.motion)
        if not isinstance(motion.get("name"), str) or not motion["name"]:
            msg = "motion must have a non-empty string 'name'"
            raise TrajectoryContentError(msg)
        if not isinstance(self.model_hash, str) or not self.model_hash:
            msg = "model_hash must be a non-empty string"
            raise TrajectoryContentError(msg)
        solver_log = _json_mapping("solver_log", self.solver_log)
        for key, value in (
            ("times", times),
            ("states", states),
            ("controls", controls),
            ("contact_wrenches", wrenches),
            ("contact_phases", phases),
            ("cop", cop),
            ("motion", motion),
            ("solver_log", solver_log),
            ("joint_names", names),
        ):
            object.__setattr__(self, key, value)

    @property
    def n_knots(self) -> int:
        """Number of knots N."""
        return int(self.times.size)

    def joint_positions(self) -> FloatArray:
        """(N, 32) joint positions [rad], JOINT_NAMES order (read-only view)."""
        return self.states[:, 7:NQ]

    def joint_velocities(self) -> FloatArray:
        """(N, 32) joint velocities [rad/s], JOINT_NAMES order (read-only view)."""
        return self.states[:, NQ + 6 :]

    def base_positions(self) -> FloatArray:
        """(N, 3) floating-base position xyz [m] (read-only view)."""
        return self.states[:, :3]

    def base_quaternions_xyzw(self) -> FloatArray:
        """(N, 4) floating-base orientation, quaternion xyzw (read-only view)."""
        return self.states[:, 3:7]

    def base_twists(self) -> FloatArray:
        """(N, 6) floating-base twist: linear xyz [m/s], angular xyz [rad/s] (read-only view)."""
        return self.states[:, NQ : NQ + 6]

    def arrays(self) -> dict[str, NDArray[Any]]:
        """The array fields by entry name, in checksum order."""
        return {name: getattr(self, name) for name in ARRAY_NAMES}

    def __eq__(self, other: object) -> bool:
        """Equal arrays (NaN equal to NaN), metadata and names."""
        if not isinstance(other, TrajectoryData):
            return NotImplemented
        mine, theirs = self.arrays(), other.arrays()
        return (
            all(np.array_equal(mine[k], theirs[k], equal_nan=mine[k].dtype.kind == "f") for k in ARRAY_NAMES)
            and self.motion == other.motion
            and self.model_hash == other.model_hash
            and self.solver_log == other.solver_log
            and self.joint_names == other.joint_names
        )

    __hash__ = None  # type: ignore[assignment]


# --------------------------------------------------------------------------------------------------
# encoding


def _storage_array(arr: NDArray[Any]) -> NDArray[Any]:
    """Array as stored: little-endian float64 or bool, C order."""
    dtype = np.dtype(np.bool_) if arr.dtype == np.bool_ else np.dtype("<f8")
    return np.ascontiguousarray(arr, dtype=dtype)


def checksum(header_bytes: bytes, arrays: Mapping[str, NDArray[Any]]) -> str:
    """Hex SHA-256 over the domain tag, the header bytes and, per array in ARRAY_NAMES order,
    ``name NUL dtype.str NUL json(shape) NUL raw bytes``."""
    digest = hashlib.sha256(CHECKSUM_DOMAIN)
    digest.update(header_bytes)
    for name in ARRAY_NAMES:
        arr = _storage_array(arrays[name])
        digest.update(f"{name}\0{arr.dtype.str}\0{json.dumps(list(arr.shape))}\0".encode())
        digest.update(arr.tobytes())
    return digest.hexdigest()


def _header(data: TrajectoryData) -> bytes:
    header = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "joint_names": list(data.joint_names),
        "model_hash": data.model_hash,
        "motion": data.motion,
        "solver_log": data.solver_log,
    }
    return (json.dumps(header, indent=1, sort_keys=True) + "\n").encode()


def _npy_bytes(arr: NDArray[Any]) -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, _storage_array(arr), allow_pickle=False)
    return buffer.getvalue()


def _write_entry(archive: zipfile.ZipFile, name: str, payload: bytes) -> None:
    info = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o644 << 16
    archive.writestr(info, payload)


def encode_trajectory(data: TrajectoryData) -> bytes:
    """The file bytes of ``data`` (what save_trajectory writes)."""
    header = _header(data)
    arrays = data.arrays()
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        _write_entry(archive, HEADER_ENTRY, header)
        for name in ARRAY_NAMES:
            _write_entry(archive, f"{name}.npy", _npy_bytes(arrays[name]))
        _write_entry(archive, CHECKSUM_ENTRY, (checksum(header, arrays) + "\n").encode())
    return buffer.getvalue()


def save_trajectory(path: str | os.PathLike[str], data: TrajectoryData, *, overwrite: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically (temp file in the same folder, fsync, rename); returns the path.

    With ``overwrite=False`` an existing file raises FileExistsError and is left untouched.
    """
    target = Path(path)
    payload = encode_trajectory(data)
    fd, tmp_name = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as file:
            file.write(payload)
            file.flush()
            os.fsync(file.fileno())
        if overwrite:
            tmp.replace(target)
        else:
            os.link(tmp, target)  # atomic and refuses an existing target
            tmp.unlink()
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    with contextlib.suppress(OSError):  # make the rename durable where directories can be fsynced
        dir_fd = os.open(target.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
    return target


# --------------------------------------------------------------------------------------------------
# decoding


def _short(digest: str) -> str:
    return digest if len(digest) <= 16 else f"{digest[:12]}..."


def _read_entry(archive: zipfile.ZipFile, name: str, label: str) -> bytes:
    try:
        return archive.read(name)
    except KeyError:
        msg = f"{label}: missing entry {name!r} (entries: {', '.join(archive.namelist())})"
        raise TrajectoryContentError(msg) from None
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, NotImplementedError) as err:
        msg = f"{label}: corrupted entry {name!r}: {err}"
        raise TrajectoryCorruptedError(msg) from None


def _parse_header(raw: bytes, label: str) -> dict[str, Any]:
    try:
        header = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as err:
        msg = f"{label}: corrupted: {HEADER_ENTRY} is not valid JSON ({err})"
        raise TrajectoryCorruptedError(msg) from None
    if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
        found = header.get("format") if isinstance(header, dict) else type(header).__name__
        msg = f"{label}: not an RH5 trajectory file ({HEADER_ENTRY} format is {found!r}, expected {FORMAT_NAME!r})"
        raise TrajectoryContentError(msg)
    version = header.get("version")
    if type(version) is not int or version not in SUPPORTED_VERSIONS:
        supported = ", ".join(map(str, SUPPORTED_VERSIONS))
        hint = " (written by a newer rh5_msgs_py: update this one)" if type(version) is int and version > 0 else ""
        msg = f"{label}: unsupported format version {version!r}: this reader supports version {supported}{hint}"
        raise TrajectoryVersionError(msg)
    return header


def load_trajectory(path: str | os.PathLike[str], expected_model_hash: str | None = None) -> TrajectoryData:
    """Read and check a trajectory file: integrity, version, content, then (if given) the model hash.

    Raises OSError if the file cannot be read and a TrajectoryFileError subclass naming the file otherwise.
    """
    label = os.fspath(path)
    raw = Path(path).read_bytes()
    if not raw:
        msg = f"{label}: truncated: the file is empty"
        raise TrajectoryTruncatedError(msg)
    if not raw.startswith(_ZIP_MAGIC):
        msg = f"{label}: corrupted: not an RH5 trajectory file (no zip signature at the start)"
        raise TrajectoryCorruptedError(msg)
    if _ZIP_END_MAGIC not in raw[-_ZIP_END_SEARCH:]:
        msg = f"{label}: truncated: the zip end record is missing ({len(raw)} bytes present)"
        raise TrajectoryTruncatedError(msg)
    try:
        archive = zipfile.ZipFile(io.BytesIO(raw))
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as err:
        msg = f"{label}: corrupted: unreadable zip directory ({err})"
        raise TrajectoryCorruptedError(msg) from None
    with archive:
        header_bytes = _read_entry(archive, HEADER_ENTRY, label)
        header = _parse_header(header_bytes, label)
        arrays: dict[str, NDArray[Any]] = {}
        for name in ARRAY_NAMES:
            payload = _read_entry(archive, f"{name}.npy", label)
            try:
                arrays[name] = np.lib.format.read_array(io.BytesIO(payload), allow_pickle=False)
            except (ValueError, OSError, EOFError) as err:
                msg = f"{label}: corrupted entry '{name}.npy': {err}"
                raise TrajectoryCorruptedError(msg) from None
        stored = _read_entry(archive, CHECKSUM_ENTRY, label).decode("ascii", "replace").strip()
    computed = checksum(header_bytes, arrays)
    if stored != computed:
        msg = f"{label}: corrupted: checksum mismatch (stored {_short(stored)}, computed {_short(computed)})"
        raise TrajectoryCorruptedError(msg)
    try:
        data = TrajectoryData(
            **arrays,
            motion=header.get("motion"),  # type: ignore[arg-type]
            model_hash=header.get("model_hash"),  # type: ignore[arg-type]
            solver_log=header.get("solver_log", {}),
            joint_names=tuple(header.get("joint_names", ())),
        )
    except TrajectoryContentError as err:
        msg = f"{label}: {err}"
        raise TrajectoryContentError(msg) from None
    if expected_model_hash is not None and data.model_hash != expected_model_hash:
        msg = (
            f"{label}: model hash mismatch: file was planned for {_short(data.model_hash)}, "
            f"this model is {_short(expected_model_hash)}"
        )
        raise ModelHashMismatchError(msg)
    return data
