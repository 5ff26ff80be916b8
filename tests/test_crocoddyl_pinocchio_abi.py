"""The Crocoddyl/Pinocchio pairing computes correct physics (design/crocoddyl_wheels.md explains the trap)."""

from __future__ import annotations

import subprocess
import sys

from rh5_planner.abi_guard import KNOWN_GOOD_PAIRS


def test_installed_versions_are_the_verified_pair() -> None:
    from importlib.metadata import version

    assert (version("crocoddyl"), version("pin")) in KNOWN_GOOD_PAIRS
    assert version("libpinocchio") == version("pin")
    assert version("libcrocoddyl") == version("crocoddyl")


def test_crocoddyl_agrees_with_pinocchio_in_a_child_process() -> None:
    """Dynamics with gravity and the foot contact Jacobian match Pinocchio's own to 1e-9.

    A child process, because a mismatched pairing can crash (out-of-bounds frame reads).
    """
    result = subprocess.run(
        [sys.executable, "-m", "rh5_planner.abi_guard"], capture_output=True, text=True, timeout=120, check=False
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert ": OK (" in result.stdout


def test_guard_detects_missing_gravity() -> None:
    """The dynamics check is sensitive to what the ABI break does: a world without gravity."""
    import crocoddyl  # noqa: F401  (import order: crocoddyl before pinocchio-linked modules)
    import numpy as np
    import pinocchio

    from rh5_hyrodyn_mapper.model import build_model

    model = build_model(free_flyer=True)
    q, v, tau = pinocchio.neutral(model), np.zeros(model.nv), np.zeros(model.nv)
    with_gravity = pinocchio.aba(model, model.createData(), q, v, tau)
    model.gravity.linear[:] = 0.0
    without_gravity = pinocchio.aba(model, model.createData(), q, v, tau)
    assert np.max(np.abs(with_gravity - without_gravity)) > 1.0  # far above the guard's 1e-9
