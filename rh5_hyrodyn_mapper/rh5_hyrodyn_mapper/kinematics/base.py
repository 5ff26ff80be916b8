"""The contract every submechanism model fulfils, and what is shared by all of them.

A submechanism maps its m independent joints y (rad) to its m actuator coordinates l
(m for linear actuators, rad for rotary drives). Models are immutable (geometry built
once); every method is vectorised over leading sample axes: ``y`` of shape (..., m)
gives ``l`` of shape (..., m) and Jacobians of shape (..., m, m), so one call maps a
whole trajectory. Statics follow from virtual power, f . l_dot = tau . y_dot:
tau = J^T f and f = J^-T tau.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def matvec(matrix: FloatArray, vector: FloatArray) -> FloatArray:
    """Matrix times vector over leading sample axes: (..., m, n) x (..., n) -> (..., m)."""
    return (matrix @ np.asarray(vector, dtype=np.float64)[..., None])[..., 0]


class KinematicsError(ValueError):
    """A submechanism cannot map the given input."""


class ForwardKinematicsError(KinematicsError):
    """Newton forward kinematics did not converge (the actuator lengths are not assemblable)."""


class SingularityError(KinematicsError):
    """A force map was refused because the actuator Jacobian is too close to singular."""


@dataclass(frozen=True)
class ActuatorLimits:
    """Per-actuator limits (paper table "ROM of linear actuators"): stroke [m], speed [m/s], force [N]."""

    length_min: FloatArray
    length_max: FloatArray
    velocity_max: FloatArray
    force_max: FloatArray


class SubmechanismModel(ABC):
    """Immutable model of one submechanism: names, geometry, actuator limits; vectorised maps."""

    name: str
    kind: str
    joints: tuple[str, ...]
    actuators: tuple[str, ...]
    limits: ActuatorLimits

    @property
    def dof(self) -> int:
        """Number of independent joints (= number of actuators on RH5)."""
        return len(self.joints)

    @abstractmethod
    def inverse(self, y: FloatArray) -> FloatArray:
        """Actuator coordinates l(y), closed form; (..., m) -> (..., m)."""

    @abstractmethod
    def jacobian(self, y: FloatArray) -> FloatArray:
        """J = dl/dy; (..., m) -> (..., m, m)."""

    @abstractmethod
    def bias(self, y: FloatArray, yd: FloatArray) -> FloatArray:
        """Acceleration bias J-dot y-dot, so that l_ddot = J y_ddot + bias; (..., m) -> (..., m)."""

    @abstractmethod
    def forward(self, l: FloatArray, y_guess: FloatArray | None = None) -> FloatArray:
        """Joints y(l); closed form or Newton warm-started from ``y_guess`` (cold start when None).

        Raises ForwardKinematicsError naming the submechanism when it does not converge.
        """

    def to_actuator_space(
        self,
        y: FloatArray,
        yd: FloatArray | None = None,
        ydd: FloatArray | None = None,
        tau: FloatArray | None = None,
        max_condition: float = 1e6,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None, FloatArray | None]:
        """All of (l, l_dot, l_ddot, f) in one call; the fields whose inputs are None come back None.

        ``ydd`` needs ``yd``. Subclasses override this to share the work between the four maps.
        """
        l = self.inverse(y)
        if yd is None and tau is None:
            return l, None, None, None
        jac = self.jacobian(y)
        ld = None if yd is None else matvec(jac, yd)
        ldd = None if ydd is None or yd is None else matvec(jac, ydd) + self.bias(y, yd)
        f = None if tau is None else self.forces(y, tau, max_condition, jac=jac)
        return l, ld, ldd, f

    def to_joint_space(
        self,
        l: FloatArray,
        ld: FloatArray | None = None,
        f: FloatArray | None = None,
        y_guess: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
        """All of (y, y_dot, tau) from actuator readings in one call (None where the input is None)."""
        y = self.forward(l, y_guess)
        if ld is None and f is None:
            return y, None, None
        jac = self.jacobian(y)
        yd = None if ld is None else np.linalg.solve(jac, np.asarray(ld, dtype=np.float64)[..., None])[..., 0]
        tau = None if f is None else self.torques(y, f, jac=jac)
        return y, yd, tau

    def _single_actuator_space(
        self,
        y: FloatArray,
        yd: FloatArray | None,
        ydd: FloatArray | None,
        tau: FloatArray | None,
        max_condition: float,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None, FloatArray | None] | None:
        """``to_actuator_space`` of ONE sample through the float path; None when the inputs are batches."""
        single = sample_lists(self.dof, y, yd, ydd, tau)
        if single is None:
            return None
        l, ld, ldd, f = self.to_actuator_space_floats(*single, max_condition)
        return np.array(l), optional_array(ld), optional_array(ldd), optional_array(f)

    def _single_joint_space(
        self,
        l: FloatArray,
        ld: FloatArray | None,
        f: FloatArray | None,
        y_guess: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None] | None:
        """``to_joint_space`` of ONE sample through the float path; None when the inputs are batches.

        Pass ``y_guess`` only where the forward kinematics uses it (it must then be one sample too).
        """
        single = sample_lists(self.dof, l, ld, f, *(() if y_guess is None else (y_guess,)))
        if single is None:
            return None
        y, yd, tau = self.to_joint_space_floats(*single)
        return np.array(y), optional_array(yd), optional_array(tau)

    def to_actuator_space_floats(
        self,
        y: Sequence[float],
        yd: Sequence[float] | None = None,
        ydd: Sequence[float] | None = None,
        tau: Sequence[float] | None = None,
        max_condition: float = 1e6,
    ) -> tuple[Sequence[float], Sequence[float] | None, Sequence[float] | None, Sequence[float] | None]:
        """``to_actuator_space`` for ONE sample given as m Python floats each (lists or tuples).

        Returns sequences of m Python floats (None where the input is None) with the same values and errors as
        ``to_actuator_space`` on arrays of shape (m,); the single-sample path of RobotMapper, which slices Python
        lists instead of arrays. Subclasses override it with plain float arithmetic; this default goes through the
        array method.
        """
        results = self.to_actuator_space(
            np.array(y, dtype=np.float64),
            None if yd is None else np.array(yd, dtype=np.float64),
            None if ydd is None else np.array(ydd, dtype=np.float64),
            None if tau is None else np.array(tau, dtype=np.float64),
            max_condition,
        )
        l, ld, ldd, f = (None if x is None else np.asarray(x, dtype=np.float64).tolist() for x in results)
        return l, ld, ldd, f

    def to_joint_space_floats(
        self,
        l: Sequence[float],
        ld: Sequence[float] | None = None,
        f: Sequence[float] | None = None,
        y_guess: Sequence[float] | None = None,
    ) -> tuple[Sequence[float], Sequence[float] | None, Sequence[float] | None]:
        """``to_joint_space`` for ONE sample given as m Python floats each (see ``to_actuator_space_floats``)."""
        results = self.to_joint_space(
            np.array(l, dtype=np.float64),
            None if ld is None else np.array(ld, dtype=np.float64),
            None if f is None else np.array(f, dtype=np.float64),
            None if y_guess is None else np.array(y_guess, dtype=np.float64),
        )
        y, yd, tau = (None if x is None else np.asarray(x, dtype=np.float64).tolist() for x in results)
        return y, yd, tau

    def forces(
        self, y: FloatArray, tau: FloatArray, max_condition: float = 1e6, jac: FloatArray | None = None
    ) -> FloatArray:
        """Actuator forces f = J^-T tau; refuses (SingularityError) where cond(J) > ``max_condition``.

        ``jac`` may pass J(y) when the caller has it already.
        """
        jac = self.jacobian(y) if jac is None else jac
        condition = np.linalg.cond(jac)
        if np.any(~(condition <= max_condition)):
            worst = float(np.nanmax(np.where(np.isfinite(condition), condition, np.inf)))
            msg = f"{self.name}: force map refused near a singular pose (cond(J) = {worst:.3g} > {max_condition:.3g})"
            raise SingularityError(msg)
        return np.linalg.solve(np.swapaxes(jac, -1, -2), tau[..., None])[..., 0]

    def torques(self, y: FloatArray, f: FloatArray, jac: FloatArray | None = None) -> FloatArray:
        """Joint torques tau = J^T f (``jac`` may pass J(y) when the caller has it already)."""
        jac = self.jacobian(y) if jac is None else jac
        return np.einsum("...ji,...j->...i", jac, f)


# --- shared helpers of the RH5 submechanism models (lambda_rrpr, ankle_sprr, spu, serial) -----------------------


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


class ImmutableModel(SubmechanismModel):
    """A SubmechanismModel whose attributes cannot be rebound once ``_freeze()`` ran (end of ``__init__``)."""

    _frozen: bool = False

    def _freeze(self) -> None:
        object.__setattr__(self, "_frozen", True)

    def __setattr__(self, name: str, value: object) -> None:
        if self._frozen:
            raise AttributeError(f"{type(self).__name__} {self.name!r} is immutable (cannot set {name!r})")
        object.__setattr__(self, name, value)

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"{type(self).__name__} {self.name!r} is immutable (cannot delete {name!r})")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, kind={self.kind!r}, joints={self.joints!r})"


def as_samples(name: str, x: npt.ArrayLike, m: int) -> FloatArray:
    """``x`` as a float64 array of shape (..., m); raises KinematicsError naming the submechanism otherwise."""
    out = np.asarray(x, dtype=np.float64)
    if out.ndim == 0 or out.shape[-1] != m:
        raise KinematicsError(f"{name}: expected shape (..., {m}), got {out.shape}")
    return out


def sample_lists(m: int, *values: npt.ArrayLike | None) -> list[list[float] | None] | None:
    """Each of ``values`` as a list of m Python floats (None stays None) when every given one is ONE sample (m,).

    None when any of them has another shape (the caller then takes its vectorised path, which validates them).
    """
    out: list[list[float] | None] = []
    for x in values:
        if x is None:
            out.append(None)
            continue
        a = np.asarray(x, dtype=np.float64)
        if a.shape != (m,):
            return None
        out.append(a.tolist())
    return out


def optional_array(values: Sequence[float] | None) -> FloatArray | None:
    """A float64 array of a float sequence, None for None (results of the single-sample paths)."""
    return None if values is None else np.array(values, dtype=np.float64)


def singular_solve() -> np.linalg.LinAlgError:
    """The error np.linalg.solve raises for an exactly singular J (closed-form 2x2 and 1x1 solves raise it too)."""
    return np.linalg.LinAlgError("Singular matrix")
