"""The actuator model's parameters and state, as Crocoddyl pairs a model with its data.

`ActuatorParams` holds the immutable parameters of all 32 actuators (built by `default_params` from the packaged
YAML and the mapper's limits, validated once); `ActuatorState` the mutable state one `ActuatorBank`
(:mod:`rh5_bringup.sim.actuators`) advances, created by `ActuatorParams.create_state`. `parameter_table`
summarises the parameters per actuator type for people.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from rh5_bringup.hardware.ndlcom.payloads import CommandMode
from rh5_hyrodyn_mapper.kinematics.base import ActuatorLimits
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import ACTUATOR_NAMES, LINEAR_ACTUATOR_NAMES, NUM_ACTUATORS

ArrayLike = npt.ArrayLike

SUBSTEPS = 4
"""Velocity-loop cycles (4 kHz) per position-loop cycle (1 kHz) [paper]."""

NOMINAL_DT = 1e-3
"""The board cycle of the position loop and of the 1 kHz driver [s]."""

PARAMETER_FILE = "actuator_params.yaml"


_ARRAY_FIELDS = (
    "position_min",
    "position_max",
    "velocity_max",
    "force_max",
    "transmission_ratio",
    "torque_constant",
    "force_constant",
    "resistance",
    "current_max",
    "inertia",
    "viscous",
    "coulomb",
    "current_time_constant",
    "kp_position",
    "ki_position",
    "braking_acceleration",
    "kp_velocity",
    "ki_velocity",
    "thermal_resistance",
    "thermal_time_constant",
    "ambient_temperature",
    "temperature_max",
    "following_error_max",
)
_NON_NEGATIVE_FIELDS = ("viscous", "coulomb", "ki_position", "ki_velocity")
"""May be zero (no friction, no integral action); every other array but the stroke ends and temperatures must be
> 0."""
_POSITIVE_FIELDS = tuple(
    f
    for f in _ARRAY_FIELDS
    if f not in {*_NON_NEGATIVE_FIELDS, "position_min", "position_max", "ambient_temperature", "temperature_max"}
)


@dataclass(frozen=True, eq=False)
class ActuatorParams:
    """Immutable parameters of all 32 actuators (ACTUATOR_NAMES order, SI units, arrays of shape (32,)).

    Built by `default_params`; validated here (shapes, signs, stroke, reachability of the force limit,
    stability of the explicit terms). Linear: m, m/s, N; rotary: rad, rad/s, Nm.
    """

    names: tuple[str, ...]
    types: tuple[str, ...]  # actuator type per actuator (wrist, torso, hip3, knee, ankle, shoulder, ...)
    linear: npt.NDArray[np.bool_]
    position_min: FloatArray  # stroke (end stops)
    position_max: FloatArray
    velocity_max: FloatArray  # no-load speed at the bus voltage
    force_max: FloatArray  # force at the current limit
    transmission_ratio: FloatArray  # N: motor rad per output m (linear) or rad (rotary)
    torque_constant: FloatArray  # k_t [Nm/A] (= back-EMF constant [V s/rad])
    force_constant: FloatArray  # K = k_t N [N/A or Nm/A]
    resistance: FloatArray  # winding resistance [Ohm]
    current_max: FloatArray  # current limit [A]
    inertia: FloatArray  # reflected inertia at the output [kg or kg m^2]
    viscous: FloatArray  # b [N s/m or Nm s/rad]
    coulomb: FloatArray  # Coulomb friction [N or Nm]
    current_time_constant: FloatArray  # first-order lag of the closed current loop [s]
    kp_position: FloatArray  # [1/s]
    ki_position: FloatArray  # [1/s^2]
    braking_acceleration: FloatArray  # deceleration the position loop plans with [m/s^2 or rad/s^2]
    kp_velocity: FloatArray  # [N s/m or Nm s/rad]
    ki_velocity: FloatArray  # [N/m or Nm/rad]
    thermal_resistance: FloatArray  # winding to ambient [K/W]
    thermal_time_constant: FloatArray  # [s]
    ambient_temperature: FloatArray  # [deg C]
    temperature_max: FloatArray  # OVERTEMPERATURE threshold [deg C]
    following_error_max: FloatArray  # FOLLOWING_ERROR threshold [m or rad]
    bus_voltage: float  # [V]
    substeps: int = SUBSTEPS

    def __post_init__(self) -> None:
        n = len(self.names)
        if len(self.types) != n:
            msg = f"ActuatorParams: {len(self.types)} types for {n} actuators"
            raise ValueError(msg)
        object.__setattr__(self, "linear", read_only(np.broadcast_to(np.asarray(self.linear, dtype=bool), (n,))))
        for name in _ARRAY_FIELDS:
            value = np.asarray(getattr(self, name), dtype=np.float64)
            try:
                value = np.broadcast_to(value, (n,))
            except ValueError:
                msg = f"ActuatorParams.{name}: shape {value.shape} does not fit {n} actuators"
                raise ValueError(msg) from None
            if not np.all(np.isfinite(value)):
                msg = f"ActuatorParams.{name}: not finite"
                raise ValueError(msg)
            object.__setattr__(self, name, read_only(value))
        for name in _POSITIVE_FIELDS:
            bad = np.flatnonzero(getattr(self, name) <= 0)
            if bad.size:
                msg = f"ActuatorParams.{name}: must be > 0 ({self.names[bad[0]]})"
                raise ValueError(msg)
        for name in _NON_NEGATIVE_FIELDS:
            bad = np.flatnonzero(getattr(self, name) < 0)
            if bad.size:
                msg = f"ActuatorParams.{name}: must be >= 0 ({self.names[bad[0]]})"
                raise ValueError(msg)
        checks = (
            (self.position_max <= self.position_min, "the stroke is empty"),
            (self.current_max * self.resistance >= self.bus_voltage, "the bus voltage cannot drive I_max"),
            (
                ~np.isclose(self.force_constant * self.current_max, self.force_max, rtol=1e-9),
                "force_max != force_constant * current_max",
            ),
            (
                ~np.isclose(self.force_constant * self.velocity_max, self.bus_voltage, rtol=1e-9),
                "velocity_max is not the no-load speed bus_voltage / force_constant",
            ),
        )
        for bad_mask, what in checks:
            bad = np.flatnonzero(bad_mask)
            if bad.size:
                msg = f"ActuatorParams: {what} ({self.names[bad[0]]})"
                raise ValueError(msg)
        if self.bus_voltage <= 0 or self.substeps < 1:
            msg = "ActuatorParams: bus_voltage must be > 0 and substeps >= 1"
            raise ValueError(msg)
        if self.max_dt < NOMINAL_DT:
            worst = self.names[int(np.argmin(self._stable_dt))]
            msg = (
                f"ActuatorParams: unstable at {NOMINAL_DT * 1e3:g} ms cycles (max {self.max_dt * 1e3:.3g} ms, {worst})"
            )
            raise ValueError(msg)

    @property
    def _stable_dt(self) -> FloatArray:
        """Per actuator, the longest cycle with h kp_v / M < 1 (sub-step) and dt K^2 / (R M) < 1 (cycle)."""
        velocity_loop = self.substeps * self.inertia / self.kp_velocity
        back_emf = self.inertia * self.resistance / self.force_constant**2
        return np.minimum(velocity_loop, back_emf)

    @property
    def max_dt(self) -> float:
        """Longest cycle [s] for which the explicitly integrated terms stay stable and overshoot-free."""
        return float(self._stable_dt.min())

    @property
    def stroke(self) -> FloatArray:
        """position_max - position_min [m or rad]."""
        return self.position_max - self.position_min

    @property
    def num(self) -> int:
        """Number of actuators."""
        return len(self.names)

    def indices(self, actuator_type: str) -> npt.NDArray[np.intp]:
        """Indices of the actuators of one type."""
        return np.flatnonzero(np.asarray(self.types) == actuator_type)

    def type_names(self) -> tuple[str, ...]:
        """The actuator types in order of first appearance."""
        return tuple(dict.fromkeys(self.types))

    def create_state(self) -> ActuatorState:
        """A state at mid-stroke, at rest, OFF (Crocoddyl's createData)."""
        return ActuatorState.zeros(self.num, 0.5 * (self.position_min + self.position_max), self.ambient_temperature)


def read_only(values: np.ndarray) -> np.ndarray:
    """A copy of ``values`` that cannot be written (parameters and coefficients are shared, never changed)."""
    out = np.array(values, copy=True)
    out.setflags(write=False)
    return out


# ----------------------------------------------------------------------------------------------------------------
# Parameters from the packaged YAML and the mapper's limits


def _load_yaml(path: str | Path | None) -> dict[str, Any]:
    if path is None:
        text = resources.files(__package__).joinpath(PARAMETER_FILE).read_text(encoding="utf-8")
    else:
        text = Path(path).read_text(encoding="utf-8")
    data = yaml.safe_load(text)
    if not isinstance(data, dict) or data.get("schema") != 1:
        msg = f"{path or PARAMETER_FILE}: not an actuator parameter file of schema 1"
        raise ValueError(msg)
    return data


def _assign_types(types: Mapping[str, Mapping[str, Any]], names: Sequence[str]) -> list[str]:
    """The type of every actuator, by the fnmatch patterns of the types; each actuator must match exactly one."""
    assigned: list[list[str]] = [[] for _ in names]
    for type_name, entry in types.items():
        for i, name in enumerate(names):
            if any(fnmatch.fnmatchcase(name, pattern) for pattern in entry["actuators"]):
                assigned[i].append(type_name)
    for name, hits in zip(names, assigned, strict=True):
        if len(hits) != 1:
            msg = f"actuator parameters: {name} matches {len(hits)} types ({hits})"
            raise ValueError(msg)
    return [hits[0] for hits in assigned]


def default_params(path: str | Path | None = None, limits: ActuatorLimits | None = None) -> ActuatorParams:
    """Parameters of all 32 actuators: type constants from the YAML (packaged by default), limits from the mapper.

    ``limits`` defaults to the mapper's (``robot_mapper().limits``: stroke, max velocity and max force per
    actuator, ACTUATOR_NAMES order). See actuator_params.yaml for the derivation and the source of every value.
    """
    data = _load_yaml(path)
    limits = robot_mapper().limits if limits is None else limits
    names = ACTUATOR_NAMES
    n = NUM_ACTUATORS
    types = data["types"]
    type_of = _assign_types(types, names)
    linear_names = set(LINEAR_ACTUATOR_NAMES)
    for name, type_name in zip(names, type_of, strict=True):
        if (types[type_name]["kind"] == "linear") != (name in linear_names):
            msg = f"actuator parameters: {name} is assigned to {types[type_name]['kind']} type {type_name}"
            raise ValueError(msg)

    def per_type(key: str) -> FloatArray:
        return np.array([float(types[t][key]) for t in type_of])

    def loop_setting(loop: str, key: str) -> FloatArray:
        default = float(data[loop][key])
        return np.array([float(types[t].get(f"{loop}_{key}", default)) for t in type_of])

    linear = np.array([name in linear_names for name in names])
    v_max = np.asarray(limits.velocity_max, dtype=np.float64)
    f_max = np.asarray(limits.force_max, dtype=np.float64)
    lo = np.asarray(limits.length_min, dtype=np.float64)
    hi = np.asarray(limits.length_max, dtype=np.float64)
    voltage = float(data["bus_voltage_v"])
    lead = np.array([float(types[t].get("lead_mm", 1.0)) * 1e-3 for t in type_of])
    gear = per_type("gear_ratio")
    ratio = np.where(linear, 2.0 * math.pi * gear / lead, gear)
    force_constant = voltage / v_max
    torque_constant = force_constant / ratio
    resistance = (torque_constant / per_type("motor_constant")) ** 2
    inertia = per_type("rotor_inertia_kgm2") * ratio**2 + per_type("output_inertia")
    w_v = 2.0 * math.pi * loop_setting("velocity_loop", "bandwidth_hz")
    kp_v = inertia * w_v
    return ActuatorParams(
        names=names,
        types=tuple(type_of),
        linear=linear,
        position_min=lo,
        position_max=hi,
        velocity_max=v_max,
        force_max=f_max,
        transmission_ratio=ratio,
        torque_constant=torque_constant,
        force_constant=force_constant,
        resistance=resistance,
        current_max=f_max / force_constant,
        inertia=inertia,
        viscous=per_type("viscous_fraction") * f_max / v_max,
        coulomb=per_type("coulomb_fraction") * f_max,
        current_time_constant=np.full(n, 1.0 / (2.0 * math.pi * float(data["current_loop_bandwidth_hz"]))),
        kp_position=2.0 * math.pi * loop_setting("position_loop", "bandwidth_hz"),
        ki_position=loop_setting("position_loop", "integral_gain"),
        braking_acceleration=loop_setting("position_loop", "braking_fraction") * f_max / inertia,
        kp_velocity=kp_v,
        ki_velocity=kp_v * w_v * loop_setting("velocity_loop", "integral_zero_ratio"),
        thermal_resistance=per_type("thermal_resistance_k_per_w"),
        thermal_time_constant=per_type("thermal_time_constant_s"),
        ambient_temperature=np.full(n, float(data["ambient_temperature_c"])),
        temperature_max=np.full(n, float(data["temperature_warning_c"])),
        following_error_max=float(data["following_error_fraction"]) * (hi - lo),
        bus_voltage=voltage,
    )


@dataclass
class ActuatorState:
    """Mutable state of all actuators (Crocoddyl's Data): plant, controllers, last commands; shape (32,) each.

    ``lag``, ``integrator`` and ``applied`` are the current loop's state, the velocity integrator and the applied
    motor force in the units the sub-step loop works in (velocity increment per sub-step, i.e. force * h / M,
    the integrator also times the current-loop factor); ``force`` and `ActuatorBank.velocity_integral` give them
    in N or Nm.
    """

    position: FloatArray
    velocity: FloatArray
    force: FloatArray  # applied motor force K i at the output [N or Nm]
    temperature: FloatArray  # winding [deg C]
    mode: npt.NDArray[np.int8]
    hold_position: FloatArray  # latched when entering HOLD
    setpoint: FloatArray  # last raw position setpoint (kept when step gets None)
    target: FloatArray  # the setpoint in effect (HOLD: the held position), clipped to the stroke
    position_error: FloatArray  # target - position at the last position-loop cycle
    position_integral: FloatArray  # velocity contribution of the position integrator
    velocity_setpoint: FloatArray  # position-loop output (incl. feed-forward), saturated
    lag: FloatArray  # current-loop state (scaled, see above)
    integrator: FloatArray  # velocity-loop integrator (scaled)
    applied: FloatArray  # applied motor force (scaled)
    cycles: int = 0

    @classmethod
    def zeros(cls, n: int, position: ArrayLike, temperature: ArrayLike) -> ActuatorState:
        """At ``position``, at rest, no current, OFF, at ``temperature``."""
        x = np.array(np.broadcast_to(np.asarray(position, dtype=np.float64), (n,)))
        z = np.zeros(n)
        return cls(
            position=x,
            velocity=z.copy(),
            force=z.copy(),
            temperature=np.array(np.broadcast_to(np.asarray(temperature, dtype=np.float64), (n,))),
            mode=np.full(n, CommandMode.OFF, dtype=np.int8),
            hold_position=x.copy(),
            setpoint=x.copy(),
            target=x.copy(),
            position_error=z.copy(),
            position_integral=z.copy(),
            velocity_setpoint=z.copy(),
            lag=z.copy(),
            integrator=z.copy(),
            applied=z.copy(),
        )

    def copy(self) -> ActuatorState:
        """A deep copy (snapshots, tests)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        return ActuatorState(**{k: v.copy() if isinstance(v, np.ndarray) else v for k, v in values.items()})


def parameter_table(params: ActuatorParams) -> list[dict[str, Any]]:
    """One row per actuator type: the first actuator's parameters (SI units)."""
    rows = []
    for type_name in params.type_names():
        i = int(params.indices(type_name)[0])
        lin = bool(params.linear[i])
        rows.append(
            {
                "type": type_name,
                "count": len(params.indices(type_name)),
                "unit": "m" if lin else "rad",
                "stroke": (float(params.position_min[i]), float(params.position_max[i])),
                "velocity_max": float(params.velocity_max[i]),
                "force_max": float(params.force_max[i]),
                "N": float(params.transmission_ratio[i]),
                "k_t": float(params.torque_constant[i]),
                "K": float(params.force_constant[i]),
                "R": float(params.resistance[i]),
                "I_max": float(params.current_max[i]),
                "M": float(params.inertia[i]),
                "b": float(params.viscous[i]),
                "F_c": float(params.coulomb[i]),
                "kp_pos": float(params.kp_position[i]),
                "kp_vel": float(params.kp_velocity[i]),
                "ki_vel": float(params.ki_velocity[i]),
                "knee_speed": float(1.0 - params.current_max[i] * params.resistance[i] / params.bus_voltage),
            }
        )
    return rows
