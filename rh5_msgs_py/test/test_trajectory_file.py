"""The trajectory file: round trip, atomic writes, and one test per failure class.

Faulty files are built by ``write_file`` below, an independent writer that follows
docs/trajectory_format.md (np.save + hashlib), so a symmetric bug in the module cannot hide.
"""

from __future__ import annotations

import hashlib
import io
import json
import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rh5_msgs_py.names import JOINT_NAMES
from rh5_msgs_py.trajectory_file import (
    NQ,
    NX,
    ModelHashMismatchError,
    TrajectoryContentError,
    TrajectoryCorruptedError,
    TrajectoryData,
    TrajectoryFileError,
    TrajectoryTruncatedError,
    TrajectoryVersionError,
    load_trajectory,
    save_trajectory,
)

ORDER = ("times", "states", "controls", "contact_wrenches", "contact_phases", "cop")
MODEL_HASH = "3f2a" + "0" * 60


def make_data(n: int = 25, *, controls_rows: int | None = None, seed: int = 1) -> TrajectoryData:
    """A valid random trajectory with unit quaternions and NaN CoPs where the foot is in the air."""
    rng = np.random.default_rng(seed)
    states = rng.normal(size=(n, NX))
    quat = rng.normal(size=(n, 4))
    states[:, 3:7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    phases = rng.random((n, 2)) > 0.3
    cop = rng.normal(scale=0.02, size=(n, 2, 2))
    cop[~phases] = np.nan
    return TrajectoryData(
        times=np.arange(n) * 0.01,
        states=states,
        controls=rng.normal(size=(n - 1 if controls_rows is None else controls_rows, 32)),
        contact_wrenches=rng.normal(size=(n, 2, 6)),
        contact_phases=phases,
        cop=cop,
        motion={"name": "squat", "parameters": {"depth_m": 0.2, "duration_s": [1.0, 2.0]}},
        model_hash=MODEL_HASH,
        solver_log={"iterations": 57, "cost": 12.5, "stop_criterion": "converged", "solve_time_s": 3.1},
    )


def header_of(data: TrajectoryData, **changes: Any) -> dict[str, Any]:
    """The documented header of ``data``, with keys replaced."""
    header = {
        "format": "rh5_trajectory",
        "version": 1,
        "joint_names": list(data.joint_names),
        "model_hash": data.model_hash,
        "motion": dict(data.motion),
        "solver_log": dict(data.solver_log),
    }
    header.update(changes)
    return header


def write_file(path: Path, header: dict[str, Any], arrays: dict[str, np.ndarray], checksum: str | None = None) -> None:
    """Write a file exactly as docs/trajectory_format.md describes it (independently of the module)."""
    header_bytes = json.dumps(header).encode()
    digest = hashlib.sha256(b"rh5traj-sha256-v1\0" + header_bytes)
    stored = {}
    for name in ORDER:
        arr = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}\0{arr.dtype.str}\0{json.dumps(list(arr.shape))}\0".encode() + arr.tobytes())
        buffer = io.BytesIO()
        np.save(buffer, arr, allow_pickle=False)
        stored[name] = buffer.getvalue()
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("header.json", header_bytes)
        for name in ORDER:
            archive.writestr(f"{name}.npy", stored[name])
        archive.writestr("sha256.txt", (checksum or digest.hexdigest()) + "\n")


@pytest.fixture
def data() -> TrajectoryData:
    """A valid trajectory."""
    return make_data()


# --------------------------------------------------------------------------------------------------
# round trip


@pytest.mark.parametrize("controls_rows", [24, 25])
def test_roundtrip(tmp_path: Path, controls_rows: int) -> None:
    """save -> load gives equal data, with N-1 or N control rows, and NaN CoPs kept."""
    data = make_data(25, controls_rows=controls_rows)
    path = save_trajectory(tmp_path / "planned.rh5traj", data)
    loaded = load_trajectory(path, expected_model_hash=MODEL_HASH)
    assert loaded == data
    assert loaded.controls.shape == (controls_rows, 32)
    assert np.isnan(loaded.cop).any()
    assert loaded.contact_phases.dtype == np.bool_
    assert loaded.motion["parameters"]["duration_s"] == [1.0, 2.0]
    assert loaded != make_data(25, controls_rows=controls_rows, seed=2)


def test_accessors_slice_the_documented_columns(data: TrajectoryData) -> None:
    """joint_positions/velocities are (N, 32) slices of X* at the documented columns, read-only."""
    assert data.joint_positions().shape == (25, 32)
    np.testing.assert_array_equal(data.joint_positions(), data.states[:, 7:39])
    np.testing.assert_array_equal(data.joint_velocities(), data.states[:, 45:77])
    np.testing.assert_array_equal(data.base_quaternions_xyzw(), data.states[:, 3:7])
    np.testing.assert_array_equal(data.base_twists(), data.states[:, NQ : NQ + 6])
    assert data.n_knots == 25
    with pytest.raises(ValueError, match="read-only"):
        data.joint_positions()[0, 0] = 1.0


def test_data_is_a_snapshot() -> None:
    """Constructing copies the inputs: later changes to the caller's arrays do not leak in."""
    states = make_data().states.copy()
    base = make_data()
    data = TrajectoryData(**{**base.arrays(), "states": states}, motion={"name": "m"}, model_hash="h")
    states[0, 0] = 1e9
    assert data.states[0, 0] != 1e9


def test_the_file_is_npz_and_deterministic(tmp_path: Path, data: TrajectoryData) -> None:
    """np.load opens the file; equal data gives identical bytes; the header is plain JSON."""
    first = save_trajectory(tmp_path / "a.rh5traj", data)
    second = save_trajectory(tmp_path / "b.rh5traj", data)
    assert first.read_bytes() == second.read_bytes()
    with np.load(first) as npz:
        np.testing.assert_array_equal(npz["states"], data.states)
        assert json.loads(npz["header.json"])["version"] == 1


def test_independent_writer_output_loads(tmp_path: Path, data: TrajectoryData) -> None:
    """A file written from the documentation alone loads: the docs describe the real format."""
    path = tmp_path / "doc.rh5traj"
    write_file(path, header_of(data), data.arrays())
    assert load_trajectory(path) == data


def test_write_is_atomic_and_can_refuse_to_overwrite(tmp_path: Path, data: TrajectoryData) -> None:
    """No temporary file remains; overwrite=False leaves an existing file untouched."""
    path = save_trajectory(tmp_path / "planned.rh5traj", data)
    before = path.read_bytes()
    with pytest.raises(FileExistsError):
        save_trajectory(path, make_data(seed=3), overwrite=False)
    assert path.read_bytes() == before
    save_trajectory(path, make_data(seed=3))
    assert load_trajectory(path) == make_data(seed=3)
    assert [p.name for p in tmp_path.iterdir()] == ["planned.rh5traj"]


# --------------------------------------------------------------------------------------------------
# one test per failure class


def test_corrupted_bytes(tmp_path: Path, data: TrajectoryData) -> None:
    """Flipped bytes inside the compressed states are caught (CRC / deflate), naming the file."""
    path = save_trajectory(tmp_path / "planned.rh5traj", data)
    raw = bytearray(path.read_bytes())
    middle = len(raw) // 2
    raw[middle : middle + 4] = bytes(b ^ 0xFF for b in raw[middle : middle + 4])
    path.write_bytes(bytes(raw))
    with pytest.raises(TrajectoryCorruptedError, match=r"planned\.rh5traj: corrupted") as info:
        load_trajectory(path)
    assert type(info.value) is TrajectoryCorruptedError


def test_checksum_mismatch(tmp_path: Path, data: TrajectoryData) -> None:
    """A consistently re-zipped file with one changed value fails the SHA-256 check."""
    path = tmp_path / "tampered.rh5traj"
    arrays = dict(data.arrays())
    write_file(path, header_of(data), arrays)
    with zipfile.ZipFile(path) as archive:
        good = archive.read("sha256.txt").decode().strip()
    tampered = arrays["controls"].copy()
    tampered[3, 4] += 1e-9
    arrays["controls"] = tampered
    write_file(path, header_of(data), arrays, checksum=good)
    with pytest.raises(TrajectoryCorruptedError, match=r"tampered\.rh5traj: corrupted: checksum mismatch"):
        load_trajectory(path)


def test_not_a_trajectory_file(tmp_path: Path) -> None:
    """A file without the zip signature is reported as such."""
    path = tmp_path / "notes.rh5traj"
    path.write_text("joint_names: [a, b]\n")
    with pytest.raises(TrajectoryCorruptedError, match="no zip signature"):
        load_trajectory(path)


@pytest.mark.parametrize("keep", [0.5, 0.98, 0.0])
def test_truncated_file(tmp_path: Path, data: TrajectoryData, keep: float) -> None:
    """A file cut short (also to nothing) raises TrajectoryTruncatedError, naming the file."""
    path = save_trajectory(tmp_path / "planned.rh5traj", data)
    raw = path.read_bytes()
    path.write_bytes(raw[: int(len(raw) * keep)])
    with pytest.raises(TrajectoryTruncatedError, match=r"planned\.rh5traj: truncated"):
        load_trajectory(path)


def test_wrong_version(tmp_path: Path, data: TrajectoryData) -> None:
    """A newer format version is refused before anything else, with a hint to update."""
    path = tmp_path / "future.rh5traj"
    write_file(path, header_of(data, version=2), data.arrays())
    with pytest.raises(TrajectoryVersionError, match=r"future\.rh5traj: unsupported format version 2.*update"):
        load_trajectory(path)
    write_file(path, header_of(data, version="1"), data.arrays())
    with pytest.raises(TrajectoryVersionError, match="unsupported format version '1'"):
        load_trajectory(path)


def test_wrong_joint_names(tmp_path: Path, data: TrajectoryData) -> None:
    """An intact file whose joint names differ from JOINT_NAMES is refused, naming the difference."""
    path = tmp_path / "swapped.rh5traj"
    names = list(JOINT_NAMES)
    names[0], names[1] = names[1], names[0]
    write_file(path, header_of(data, joint_names=names), data.arrays())
    with pytest.raises(TrajectoryContentError, match=r"swapped\.rh5traj: joint names differ.*other order"):
        load_trajectory(path)
    names[0] = "Waist"
    write_file(path, header_of(data, joint_names=names), data.arrays())
    with pytest.raises(TrajectoryContentError, match=r"missing \['BodyRoll'\], unknown \['Waist'\]"):
        load_trajectory(path)


def test_wrong_shapes(tmp_path: Path, data: TrajectoryData) -> None:
    """An intact file with a state dimension off by one is refused, naming the array and both shapes."""
    path = tmp_path / "short.rh5traj"
    arrays = {**data.arrays(), "states": data.states[:, :-1]}
    write_file(path, header_of(data), arrays)
    with pytest.raises(TrajectoryContentError, match=r"short\.rh5traj: states must have shape \(25, 77\), got"):
        load_trajectory(path)


def test_missing_entry(tmp_path: Path, data: TrajectoryData) -> None:
    """An intact zip without one of the arrays names the missing entry."""
    path = save_trajectory(tmp_path / "planned.rh5traj", data)
    stripped = tmp_path / "stripped.rh5traj"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(stripped, "w") as dst:
        for item in src.infolist():
            if item.filename != "cop.npy":
                dst.writestr(item, src.read(item))
    with pytest.raises(TrajectoryContentError, match=r"missing entry 'cop\.npy'"):
        load_trajectory(stripped)


def test_model_hash_mismatch(tmp_path: Path, data: TrajectoryData) -> None:
    """Loading for another model names both hashes; without an expected hash nothing is checked."""
    path = save_trajectory(tmp_path / "planned.rh5traj", data)
    other = "9c1b" + "f" * 60
    with pytest.raises(
        ModelHashMismatchError,
        match=r"planned\.rh5traj: model hash mismatch: file was planned for 3f2a0000.*, this model is 9c1bffff",
    ):
        load_trajectory(path, expected_model_hash=other)
    assert load_trajectory(path).model_hash == MODEL_HASH


def test_errors_share_one_base() -> None:
    """Callers can catch every format problem as TrajectoryFileError (a ValueError)."""
    for cls in (
        TrajectoryCorruptedError,
        TrajectoryTruncatedError,
        TrajectoryVersionError,
        TrajectoryContentError,
        ModelHashMismatchError,
    ):
        assert issubclass(cls, TrajectoryFileError)
    assert issubclass(TrajectoryFileError, ValueError)


# --------------------------------------------------------------------------------------------------
# validation of in-memory data


def _with(data: TrajectoryData, **changes: Any) -> dict[str, Any]:
    fields = {
        **data.arrays(),
        "motion": data.motion,
        "model_hash": data.model_hash,
        "solver_log": data.solver_log,
        "joint_names": data.joint_names,
    }
    fields.update(changes)
    return fields


def _bad_quaternion(data: TrajectoryData) -> np.ndarray:
    states = data.states.copy()
    states[4, 3:7] = (0.0, 0.0, 0.0, 2.0)
    return states


def _nan_state(data: TrajectoryData) -> np.ndarray:
    states = data.states.copy()
    states[2, 40] = np.nan
    return states


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: {"times": d.times[::-1]}, "increase strictly"),
        (lambda _: {"times": np.zeros((0,))}, "N >= 1"),
        (lambda d: {"states": _bad_quaternion(d)}, r"states\[4, 3:7\].*norm 2"),
        (lambda d: {"states": _nan_state(d)}, r"non-finite value nan at index \(2, 40\)"),
        (lambda d: {"controls": d.controls[:-2]}, "controls"),
        (lambda d: {"contact_phases": d.contact_phases.astype(float) * 2}, "bool"),
        (lambda d: {"contact_wrenches": d.contact_wrenches[:, :1]}, r"contact_wrenches must have shape \(25, 2, 6\)"),
        (lambda _: {"cop": np.full((25, 2, 2), np.inf)}, "non-finite value inf"),
        (lambda _: {"motion": {"parameters": {}}}, "'name'"),
        (lambda _: {"motion": {"name": "m", "bad": object()}}, "JSON"),
        (lambda _: {"model_hash": ""}, "model_hash"),
        (lambda _: {"joint_names": JOINT_NAMES[:-1]}, r"missing \['LRAnklePitch'\]"),
    ],
)
def test_invalid_data_is_rejected(data: TrajectoryData, change: Any, message: str) -> None:
    """Each kind of invalid content raises TrajectoryContentError naming the problem."""
    with pytest.raises(TrajectoryContentError, match=message):
        TrajectoryData(**_with(data, **change(data)))


def test_phases_accept_zero_one_integers(data: TrajectoryData) -> None:
    """0/1 integer contact phases are converted to bool."""
    converted = TrajectoryData(**_with(data, contact_phases=data.contact_phases.astype(np.int8)))
    assert converted.contact_phases.dtype == np.bool_
    assert converted == data


def test_module_imports_no_ros() -> None:
    """trajectory_file loads without rclpy or any message package (offline tools use it)."""
    code = (
        "import sys, rh5_msgs_py.trajectory_file\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in "
        "{'rclpy', 'rosidl_parser', 'rpyutils'} or m.split('.')[0].endswith('_msgs'))\n"
        "print(bad)\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60)
    assert result.stdout.strip() == "[]", result.stdout
