"""The contract every submechanism model fulfils, and its one implementation over the C kernels (kernels.py).

A submechanism maps its m independent joints y (rad) to its m actuator coordinates l (m for linear actuators, rad
for rotary drives). Models are immutable (geometry built once) and hold their constants as one kernel row; every
method takes any leading sample shape: ``y`` of shape (..., m) gives ``l`` of shape (..., m) and Jacobians of shape
(..., m, m), so one call maps a whole trajectory and one sample is a batch of one. Statics follow from virtual
power, f . l_dot = tau . y_dot: tau = J^T f and f = J^-T tau. Subclasses give the constants and the error texts.
"""

from __future__ import annotations

import functools
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from rh5_msgs_py.array_types import FloatArray

from . import kernels


class KinematicsError(ValueError):
    """A submechanism cannot map the given input."""


class ForwardKinematicsError(KinematicsError):
    """Newton forward kinematics did not converge (the actuator lengths are not assemblable)."""


class SingularityError(KinematicsError):
    """A force map was refused because the actuator Jacobian is too close to singular."""


@dataclass(frozen=True)
class ActuatorLimits:
    """Per-actuator limits (paper table "ROM of linear actuators"): stroke [m], speed [m/s], force [N] (rad, rad/s
    and Nm for the rotary drives). ``clamp`` is the one place where setpoints are clamped to them."""

    length_min: FloatArray
    length_max: FloatArray
    velocity_max: FloatArray
    force_max: FloatArray

    @functools.cached_property
    def box(self) -> tuple[FloatArray, FloatArray]:
        """(low, high), each (3, n): the position, velocity and force range of every setpoint."""
        low = frozen_array(np.stack([self.length_min, -self.velocity_max, -self.force_max]))
        high = frozen_array(np.stack([self.length_max, self.velocity_max, self.force_max]))
        return low, high

    def clamp(
        self, setpoints: FloatArray, box: tuple[FloatArray, FloatArray] | None = None
    ) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        """``setpoints`` (3, ..., n: position, velocity, force rows) clamped into ``box`` (default: these limits;
        the driver passes them intersected with the wire's range), and per actuator (and sample) whether any of its
        three values was moved. NaN stays NaN: callers refuse non-finite setpoints before."""
        low, high = self.box if box is None else box
        if setpoints.ndim > 2:  # a batch: the bounds broadcast over the sample axes
            shape = (3, *(1,) * (setpoints.ndim - 2), low.shape[-1])
            low, high = low.reshape(shape), high.reshape(shape)
        clamped = np.clip(setpoints, low, high)
        return clamped, (clamped != setpoints).any(axis=0)


def frozen_array(values: npt.ArrayLike) -> FloatArray:
    """A read-only float64 copy of ``values`` (model geometry and limits never change after construction)."""
    out = np.array(values, dtype=np.float64)
    out.setflags(write=False)
    return out


def actuator_limits(
    length_min: npt.ArrayLike, length_max: npt.ArrayLike, velocity_max: npt.ArrayLike, force_max: npt.ArrayLike
) -> ActuatorLimits:
    """ActuatorLimits with read-only float64 arrays."""
    return ActuatorLimits(
        length_min=frozen_array(length_min),
        length_max=frozen_array(length_max),
        velocity_max=frozen_array(velocity_max),
        force_max=frozen_array(force_max),
    )


def as_samples(name: str, x: npt.ArrayLike, m: int) -> FloatArray:
    """``x`` as a C-contiguous float64 array of shape (..., m); raises KinematicsError naming the submechanism
    otherwise."""
    out = np.asarray(x, dtype=np.float64)
    if out.ndim == 0 or out.shape[-1] != m:
        raise KinematicsError(f"{name}: expected shape (..., {m}), got {out.shape}")
    return np.ascontiguousarray(out)


def common_samples(arrays: Sequence[FloatArray | None]) -> tuple[tuple[int, ...], int, Sequence[FloatArray | None]]:
    """The common (broadcast) shape (..., m) of C-contiguous sample arrays, its sample count, and each in that shape,
    still C-contiguous (None stays None): what the kernels read. Next to free when the shapes agree (1 kHz call)."""
    shape = arrays[0].shape
    for x in arrays:
        if x is not None and x.shape != shape:
            shape = np.broadcast_shapes(*(x.shape for x in arrays if x is not None))
            arrays = [None if x is None else np.ascontiguousarray(np.broadcast_to(x, shape)) for x in arrays]
            break
    return shape, arrays[0].size // shape[-1], arrays


def singular_solve() -> np.linalg.LinAlgError:
    """The error np.linalg.solve raises for an exactly singular J (the kernels' rate solves raise it too)."""
    return np.linalg.LinAlgError("Singular matrix")


class SubmechanismModel(ABC):
    """Immutable model of one submechanism: names, geometry, actuator limits; the maps run in the C kernels."""

    name: str
    kind: str
    joints: tuple[str, ...]
    actuators: tuple[str, ...]
    limits: ActuatorLimits
    _table: FloatArray  # this unit's kernel row, as a table of one

    @property
    def dof(self) -> int:
        """Number of independent joints (= number of actuators on RH5)."""
        return len(self.joints)

    # --- what a subclass gives ----------------------------------------------------------------------------------

    @abstractmethod
    def kernel_constants(self) -> tuple[int, list[float]]:
        """The unit's kernel kind and the constants of its row (layout in ``unit_maps.h``)."""

    @abstractmethod
    def _refusal(self, conditions: FloatArray, max_condition: float) -> str:
        """Why a force map is refused, given each sample's condition number."""

    def _forward_error(self, l: FloatArray, info: FloatArray) -> KinematicsError:
        """The error of a failed forward map: ``l`` (n, m) and per sample (status, residual) from the kernel."""
        del l
        return ForwardKinematicsError(f"{self.name}: forward kinematics failed (status {info[:, 0].min():g})")

    def kernel_row(self, joint: int = 0, actuator: int = 0) -> list[float]:
        """The unit's kernel row with its first joint and actuator at these indices of the whole-robot vectors."""
        kind, constants = self.kernel_constants()
        return kernels.row(kind, self.dof, constants, joint, actuator)

    def _set_table(self) -> None:
        object.__setattr__(self, "_table", kernels.table([self.kernel_row()]))

    # --- the maps -------------------------------------------------------------------------------------------------

    def to_actuator_space(
        self,
        y: FloatArray,
        yd: FloatArray | None = None,
        ydd: FloatArray | None = None,
        tau: FloatArray | None = None,
        max_condition: float = 1e6,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None, FloatArray | None]:
        """(l, l_dot = J y_dot, l_ddot = J y_ddot + bias, f = J^-T tau) in one call; None where the input is None.

        ``ydd`` needs ``yd`` (no l_ddot without it). Raises SingularityError, with the reason, when forces are asked
        for where the condition number exceeds ``max_condition``.
        """
        m = self.dof
        if yd is None:
            ydd = None
        given = [None if x is None else as_samples(self.name, x, m) for x in (y, yd, ydd, tau)]
        shape, n, inputs = common_samples(given)
        l, ld, ldd, f = (None if x is None else np.empty(shape) for x in inputs)
        info = np.empty((n, 2))
        if n and kernels.ik(self._table, n, *inputs, max_condition, l, ld, ldd, f, info) >= 0:
            raise SingularityError(self._refusal(info[:, 1], max_condition))
        return l, ld, ldd, f

    def to_joint_space(
        self,
        l: FloatArray,
        ld: FloatArray | None = None,
        f: FloatArray | None = None,
        y_guess: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
        """(y, y_dot = J^-1 l_dot, tau = J^T f) from actuator readings, J at exactly the returned y (None where the
        input is None). ``y_guess`` warm-starts Newton (cold start from J(0) when None). Raises
        ForwardKinematicsError naming the submechanism when the lengths do not assemble."""
        y, yd, tau, _ = self._forward(l, ld, f, y_guess)
        return y, yd, tau

    def forward_with_info(self, l: FloatArray, y_guess: FloatArray | None = None) -> tuple[FloatArray, Any]:
        """Joints y(l) and the Newton iterations per sample (an int for one sample, else an int array; 0: closed
        form)."""
        y, _, _, iterations = self._forward(l, None, None, y_guess)
        return y, iterations

    def _forward(
        self, l: FloatArray, ld: FloatArray | None, f: FloatArray | None, y_guess: FloatArray | None
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None, Any]:
        m = self.dof
        given = [None if x is None else as_samples(self.name, x, m) for x in (l, ld, f, y_guess)]
        shape, n, inputs = common_samples(given)
        y, yd, tau = (None if x is None else np.empty(shape) for x in inputs[:3])
        info = np.zeros((n, 2))
        if n and kernels.fk(self._table, n, *inputs, y, yd, tau, info) >= 0:
            status = info[:, 0]
            if np.any((status < 0) & (status != kernels.FK_SINGULAR)):
                raise self._forward_error(np.reshape(inputs[0], (n, m)), info)
            raise singular_solve()
        iterations = info[:, 0].astype(np.int64)
        return y, yd, tau, (int(iterations[0]) if len(shape) == 1 else iterations.reshape(shape[:-1]))

    def inverse(self, y: FloatArray) -> FloatArray:
        """Actuator coordinates l(y), closed form; (..., m) -> (..., m)."""
        return self.to_actuator_space(y)[0]

    def forward(self, l: FloatArray, y_guess: FloatArray | None = None) -> FloatArray:
        """Joints y(l); closed form or Newton warm-started from ``y_guess`` (cold start when None).

        Raises ForwardKinematicsError naming the submechanism when it does not converge.
        """
        return self._forward(l, None, None, y_guess)[0]

    def _pose(self, y: FloatArray, yd: FloatArray | None, what: str) -> FloatArray:
        """One of the kernel's pose outputs, "jacobian" (..., m, m), "bias" (..., m) or "condition" (...)."""
        m = self.dof
        shape, n, (y, yd) = common_samples([as_samples(self.name, y, m), yd])
        sizes = {"jacobian": (m, m), "bias": (m,), "condition": ()}
        out = np.empty((*shape[:-1], *sizes[what]))
        if n:
            kernels.pose(self._table, n, y, yd, *(out if what == key else None for key in sizes))
        return out

    def jacobian(self, y: FloatArray) -> FloatArray:
        """J = dl/dy; (..., m) -> (..., m, m)."""
        return self._pose(y, None, "jacobian")

    def bias(self, y: FloatArray, yd: FloatArray) -> FloatArray:
        """Acceleration bias J-dot y-dot, so that l_ddot = J y_ddot + bias; (..., m) -> (..., m)."""
        return self._pose(y, as_samples(self.name, yd, self.dof), "bias")

    def condition(self, y: FloatArray) -> FloatArray:
        """The condition number the force map's singularity guard uses; (..., m) -> (...)."""
        return self._pose(y, None, "condition")

    def forces(
        self, y: FloatArray, tau: FloatArray, max_condition: float = 1e6, jac: FloatArray | None = None
    ) -> FloatArray:
        """Actuator forces f = J^-T tau; refuses (SingularityError) where the condition exceeds ``max_condition``.

        ``jac`` is accepted for callers that have J(y) already; the kernel evaluates the pose anyway.
        """
        del jac
        f = self.to_actuator_space(y, None, None, tau, max_condition)[3]
        assert f is not None
        return f

    def torques(self, y: FloatArray, f: FloatArray, jac: FloatArray | None = None) -> FloatArray:
        """Joint torques tau = J^T f (``jac`` may pass J(y) when the caller has it already)."""
        jac = self.jacobian(y) if jac is None else np.asarray(jac, dtype=np.float64)
        return np.einsum("...ji,...j->...i", jac, np.asarray(f, dtype=np.float64))


class ImmutableModel(SubmechanismModel):
    """A SubmechanismModel whose attributes cannot be rebound once ``_freeze()`` ran (end of ``__init__``)."""

    _frozen: bool = False

    def __init__(
        self, name: str, kind: str, joints: Sequence[str], actuators: Sequence[str], limits: ActuatorLimits
    ) -> None:
        self.name = name
        self.kind = kind
        self.joints = tuple(joints)
        self.actuators = tuple(actuators)
        self.limits = limits

    def _freeze(self) -> None:
        """Write the kernel table from the finished constants, then refuse every later change."""
        self._set_table()
        object.__setattr__(self, "_frozen", True)

    def __setattr__(self, name: str, value: object) -> None:
        if self._frozen:
            raise AttributeError(f"{type(self).__name__} {self.name!r} is immutable (cannot set {name!r})")
        object.__setattr__(self, name, value)

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"{type(self).__name__} {self.name!r} is immutable (cannot delete {name!r})")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, kind={self.kind!r}, joints={self.joints!r})"
