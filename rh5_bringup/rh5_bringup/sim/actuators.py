"""Vectorised model of the 32 RH5 actuators and their board control, for the simulated hardware at 1 kHz.

Each board of RH5 runs a cascade of current (32 kHz), velocity (4 kHz) and position (1 kHz) loops with
velocity and current feed-forward inputs (paper, "Decentralized Actuator-Level Controllers"). This module
emulates all 32 actuator coordinates (names.ACTUATOR_NAMES order; lengths in m and forces in N for the 14
linear actuators, angles in rad and torques in Nm for the rotary drives) as arrays of shape (32,), split
Crocoddyl-style into immutable parameters (`ActuatorParams`, built by `default_params`) and mutable state
(`ActuatorState`), both held by an `ActuatorBank` that is ``reset`` once and then ``step``-ped every 1 ms.

Plant, per actuator, reduced to the output coordinate:

* motor + transmission (ball screw lead and gear stage, or gearbox) with reflected inertia
  M = J_rotor N^2 + output inertia; motor force K i with K = k_t N;
* viscous (b v) and Coulomb friction (set-valued and integrated implicitly: the actuator sticks while the
  other forces stay below the Coulomb level; no chatter, no smoothing parameter);
* current limit I_max = force_max / K: the board's current limit is what makes the force limit;
* voltage limit: the drive cannot push current against a back-EMF above the bus voltage, so the force that
  can accelerate the actuator falls to zero at the no-load speed K v = U. The paper's max velocity is taken
  as that no-load speed: the motor cannot drive the actuator beyond it (an overpowering load can). The force
  window is evaluated once per cycle from the velocity at its start; dt K^2 / (R M) < 1 keeps that stable
  and free of overshoot. Overdriven, the drive brakes with at most its limit current (uncontrolled
  regeneration through the bridge diodes is not modelled);
* end stops at the stroke limits as a hard clamp, once per cycle: a position beyond the stroke is put back
  on the stop and the velocity is zeroed (an inelastic impact, like the rubber bumpers of a real actuator).
  Chosen over a stiff spring-damper because the stroke is then never exceeded by construction, whereas a
  spring stiff enough to keep the penetration below 0.1 mm at 5.8 kN would be unstable at 4 kHz on the
  light rotary drives. Within the cycle of the impact the velocity loop still sees the pre-impact speed;
* winding temperature: one thermal node, C dT/dt = i^2 R - (T - T_amb) / R_th, integrated exactly per cycle.

Board control, per actuator:

* position loop, once per `step`: v_sp = sign(e) min(kp |e|, sqrt(2 a_brake |e|)) (+ ki integral)
  (+ velocity feed-forward), saturated at +-velocity_max, with e = x_sp - x and x_sp clipped to the stroke
  (the boards' software limits). The square-root braking curve (a_brake = 70 % of F_max / M) only acts on
  large errors; it keeps a P loop that saturates in speed from overshooting when kp v_max exceeds the
  deceleration the force limit allows (ankle, elbow, head);
* velocity PI loop, `SUBSTEPS` = 4 sub-steps of dt/4 (4 kHz): F = kp_v (v_sp - v) + I (+ force
  feed-forward), limited to the force window; the integrator is frozen while the output is limited
  (conditional integration, the anti-windup);
* current loop as a first-order lag of the demanded force with the bandwidth of a 32 kHz loop (2.5 kHz,
  tau = 64 us), integrated exactly over each 250 us sub-step, then limited. Adequate because the closed
  current loop of a 32 kHz board is a low-pass at a few kHz: it hides the winding's L/R pole and the PWM
  ripple, and at the 120 Hz crossover of the velocity loop it adds ~3 degrees of phase; sub-stepping at
  32 kHz would resolve nothing the 1 kHz telemetry can see, at eight times the cost.

Integration is semi-implicit (symplectic) Euler: per sub-step the velocity is updated first, implicitly in
viscous and Coulomb friction; the position then advances with the new velocities. The explicit terms (the
velocity P gain per sub-step, the back-EMF slope per cycle) are checked against ``ActuatorParams.max_dt``
(1.5 ms at the defaults); `step` refuses longer cycles.

Modes per actuator (`CommandMode`): OFF (power stage off: no current, free), HOLD (hold the position measured on
entering HOLD), POSITION (track the setpoint; feed-forward ignored), POSITION_FF (with velocity and force
feed-forward). Measured outputs (`ActuatorMeasurement`): position, velocity, force (the motor force at the
output, K i, as a board estimates it from its current), current, winding temperature, `ActuatorFlags`.
Sign convention: a positive force pushes towards a larger length/angle; ``external_force`` is what the
environment applies at the output (0 or a constant load in kinematic mode, from the rigid-body simulation
in physics mode), held constant over the cycle.

Cost: ~17 numpy calls on (32,) arrays per sub-step and ~50 per cycle, about 45 us per 1 ms cycle for all
32 actuators on the development machine; ``bench/sim_actuators.py`` measures it against its 100 us budget
and prints the derived parameters per actuator type.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from enum import IntFlag
from importlib import resources
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import numpy as np
import numpy.typing as npt
import yaml

from rh5_bringup.ndlcom.payloads import CommandMode
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py.names import ACTUATOR_NAMES, LINEAR_ACTUATOR_NAMES, NUM_ACTUATORS

FloatArray = npt.NDArray[np.float64]
ArrayLike = npt.ArrayLike

SUBSTEPS = 4
"""Velocity-loop cycles (4 kHz) per position-loop cycle (1 kHz) [paper]."""

NOMINAL_DT = 1e-3
"""The board cycle of the position loop and of the 1 kHz driver [s]."""

PARAMETER_FILE = "actuator_params.yaml"


class ActuatorFlags(IntFlag):
    """What the actuator model reports of one actuator per step (one byte each); ``boards.wire_flags`` turns them into
    the telemetry's status and error bits."""

    ENABLED = 1  # power stage on (mode is not OFF)
    AT_LIMIT = 2  # on an end stop (position at the stroke limit)
    CURRENT_LIMIT = 4  # SATURATED: the current is held at the current limit, i.e. the force is at force_max
    VOLTAGE_LIMIT = 8  # the current is limited by the back-EMF (near the no-load speed), not by the limit
    VELOCITY_LIMIT = 16  # the position loop's velocity setpoint is clipped at velocity_max
    SETPOINT_CLIPPED = 32  # the position setpoint lies outside the stroke and was clipped
    FOLLOWING_ERROR = 64  # |target - position| beyond following_error_max (at the start of the cycle)
    OVERTEMPERATURE = 128  # winding temperature above temperature_max


class LimitSource(Protocol):
    """Anything with the four actuator-limit arrays of `rh5_hyrodyn_mapper.mapping.RobotMapper`."""

    length_min: FloatArray
    length_max: FloatArray
    velocity_max: FloatArray
    force_max: FloatArray


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
        object.__setattr__(self, "linear", _frozen(np.broadcast_to(np.asarray(self.linear, dtype=bool), (n,))))
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
            object.__setattr__(self, name, _frozen(value))
        positive = (
            "velocity_max",
            "force_max",
            "transmission_ratio",
            "torque_constant",
            "force_constant",
            "resistance",
            "current_max",
            "inertia",
            "current_time_constant",
            "kp_position",
            "braking_acceleration",
            "kp_velocity",
            "thermal_resistance",
            "thermal_time_constant",
            "following_error_max",
        )
        for name in positive:
            bad = np.flatnonzero(getattr(self, name) <= 0)
            if bad.size:
                msg = f"ActuatorParams.{name}: must be > 0 ({self.names[bad[0]]})"
                raise ValueError(msg)
        for name in ("viscous", "coulomb", "ki_position", "ki_velocity"):
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


def _frozen(values: np.ndarray) -> np.ndarray:
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


def default_params(path: str | Path | None = None, limits: LimitSource | None = None) -> ActuatorParams:
    """Parameters of all 32 actuators: type constants from the YAML (packaged by default), limits from the mapper.

    ``limits`` defaults to `rh5_hyrodyn_mapper.mapping.robot_mapper()` (stroke, max velocity and max force per
    actuator, ACTUATOR_NAMES order). See actuator_params.yaml for the derivation and the source of every value.
    """
    data = _load_yaml(path)
    limits = robot_mapper() if limits is None else limits
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


# ----------------------------------------------------------------------------------------------------------------
# State, measurements and the bank


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


class ActuatorMeasurement(NamedTuple):
    """What the boards report after a cycle (fresh arrays, ACTUATOR_NAMES order)."""

    position: FloatArray  # m or rad
    velocity: FloatArray  # m/s or rad/s
    force: FloatArray  # motor force at the output K i [N or Nm]
    current: FloatArray  # A
    temperature: FloatArray  # winding, deg C
    status: npt.NDArray[np.uint8]  # ActuatorFlags bits


class _Coefficients(NamedTuple):
    """Per-cycle coefficient arrays for one cycle length and one mode vector (rebuilt only when either changes).

    ``s = h / M`` turns a force into the velocity increment of one sub-step; ``alpha`` is the current loop's
    step response after one sub-step. Gains are zero for actuators that are OFF.
    """

    dt: float
    scale: FloatArray  # s = h / M
    alpha: FloatArray
    beta: FloatArray  # 1 - alpha
    kp_pos: FloatArray
    ki_pos_dt: FloatArray
    ff_gain: FloatArray  # 1 in POSITION_FF
    ff_scale: FloatArray  # force feed-forward -> scaled integrator units
    akp: FloatArray  # alpha kp_v s
    aki: FloatArray  # alpha ki_v h s
    emf_a: FloatArray  # K U / R * s (voltage limit at standstill)
    neg_emf_a: FloatArray
    emf_c: FloatArray  # K^2 / R * s (back-EMF slope)
    fcap2: FloatArray  # (2, n): the current limit as force, scaled, for both rows of the force window
    neg_fcap2: FloatArray
    coulomb: FloatArray  # Coulomb friction, scaled
    neg_coulomb: FloatArray
    damping: FloatArray  # 1 / (1 + h b / M)
    h: FloatArray
    inv_scale: FloatArray
    thresholds: FloatArray  # (5, n): the right-hand sides of the status comparisons
    thermal_decay: FloatArray
    thermal_c0: FloatArray
    thermal_c1: FloatArray
    hold: npt.NDArray[np.bool_]
    any_hold: bool
    any_ff: bool


# ActuatorFlags rows: ENABLED, SETPOINT_CLIPPED, VOLTAGE_LIMIT, then the five comparisons value >= threshold of
# `_Coefficients.thresholds` (upper stop, lower stop, current limit, velocity limit, following error), then
# OVERTEMPERATURE. The two end-stop rows exclude each other, so their weights may add up.
_STATUS_WEIGHTS = np.array(
    [
        ActuatorFlags.ENABLED,
        ActuatorFlags.SETPOINT_CLIPPED,
        ActuatorFlags.VOLTAGE_LIMIT,
        ActuatorFlags.AT_LIMIT,
        ActuatorFlags.AT_LIMIT,
        ActuatorFlags.CURRENT_LIMIT,
        ActuatorFlags.VELOCITY_LIMIT,
        ActuatorFlags.FOLLOWING_ERROR,
        ActuatorFlags.OVERTEMPERATURE,
    ],
    dtype=np.uint8,
)
_INT8 = np.dtype(np.int8)


class ActuatorBank:
    """All 32 actuators with their boards: ``reset`` once, then one ``step`` per 1 ms cycle."""

    def __init__(self, params: ActuatorParams | None = None) -> None:
        self.params = default_params() if params is None else params
        p = self.params
        n = p.num
        self._shape = (n,)
        self.state = p.create_state()
        self._use_position_integral = bool(np.any(p.ki_position > 0))
        self._neg_v_max = _frozen(-p.velocity_max)
        self._two_a_brake = _frozen(2.0 * p.braking_acceleration)
        self._inv_force_constant = _frozen(1.0 / p.force_constant)
        self._zeros = _frozen(np.zeros(n))
        self._coef: _Coefficients | None = None
        self._mode_key = b""
        # scratch buffers: nothing is allocated inside the sub-step loop
        self._ev, self._tmp, self._w, self._vsum, self._xn, self._ff, self._clo, self._chi = (
            np.zeros(n) for _ in range(8)
        )
        self._window = np.zeros((2, n))  # [hi; lo]: the force window of the cycle
        self._window_rows = tuple(self._window)
        self._ok = np.zeros(n, dtype=bool)
        self._monitor = np.zeros((5, n))
        self._monitor_rows = tuple(self._monitor)
        self._flags = np.zeros((len(_STATUS_WEIGHTS), n), dtype=bool)
        self._flag_rows = tuple(self._flags)
        self._compared = self._flags[3:8]
        self._flags_u8 = self._flags.view(np.uint8)

    # --- commands ---------------------------------------------------------------------------------------------

    def reset(
        self, position: ArrayLike | None = None, velocity: ArrayLike | None = None, temperature: ArrayLike | None = None
    ) -> ActuatorMeasurement:
        """Start over at ``position`` (default mid-stroke; clipped to the stroke), OFF, no current, integrators zero."""
        p = self.params
        x = 0.5 * (p.position_min + p.position_max) if position is None else position
        x = np.clip(np.broadcast_to(np.asarray(x, dtype=np.float64), (p.num,)), p.position_min, p.position_max)
        self.state = ActuatorState.zeros(p.num, x, p.ambient_temperature if temperature is None else temperature)
        if velocity is not None:
            self.state.velocity[:] = velocity
        self._mode_key = b""
        self._coef = None
        self._flags[:] = False
        return self.measure()

    def step(  # noqa: PLR0917 - positional in the order of a board command: mode, setpoint, feed-forwards
        self,
        dt: float,
        mode: int | ArrayLike,
        setpoint: ArrayLike | None = None,
        velocity_ff: ArrayLike | None = None,
        force_ff: ArrayLike | None = None,
        external_force: ArrayLike | None = None,
    ) -> ActuatorMeasurement:
        """Advance one board cycle of ``dt`` (nominally 1 ms): the position loop once, then `SUBSTEPS` velocity cycles.

        ``mode``: one `CommandMode` for all or one per actuator. ``setpoint`` None keeps the last setpoint; the
        feed-forwards act in POSITION_FF only; ``external_force`` (None = 0) acts at the output, constant over
        the cycle. Arrays have shape (32,). Returns the measurement at the end of the cycle.
        """
        c = self._set_mode(mode, dt)
        st, p = self.state, self.params
        add, sub, mul, minimum, maximum, equal = np.add, np.subtract, np.multiply, np.minimum, np.maximum, np.equal
        flags = self._flag_rows
        x, v, tmp = st.position, st.velocity, self._tmp

        # position loop (1 kHz): v_sp = kp (x_sp - x) [+ ki integral] [+ v_ff], within +-v_max
        if setpoint is not None:
            np.copyto(st.setpoint, setpoint)
        source = st.setpoint
        if c.any_hold:
            np.copyto(tmp, source)
            np.copyto(tmp, st.hold_position, where=c.hold)
            source = tmp
        target = st.target
        minimum(source, p.position_max, out=target)
        maximum(target, p.position_min, out=target)
        np.not_equal(target, source, flags[1])
        np.logical_and(flags[1], flags[0], flags[1])  # a setpoint matters only with the power stage on
        epos, vsp = st.position_error, st.velocity_setpoint
        sub(target, x, epos)
        # P with a braking curve: |v_fb| = min(kp |e|, sqrt(2 a_brake |e|)), so the actuator can stop at the target
        np.abs(epos, vsp)
        mul(vsp, self._two_a_brake, tmp)
        np.sqrt(tmp, tmp)
        mul(vsp, c.kp_pos, vsp)
        minimum(vsp, tmp, out=vsp)
        np.copysign(vsp, epos, vsp)
        if self._use_position_integral:
            pint = st.position_integral
            mul(c.ki_pos_dt, epos, tmp)
            add(pint, tmp, pint)
            minimum(pint, p.velocity_max, out=pint)
            maximum(pint, self._neg_v_max, out=pint)
            add(vsp, pint, vsp)
        if c.any_ff and velocity_ff is not None:
            mul(velocity_ff, c.ff_gain, tmp)
            add(vsp, tmp, vsp)
        minimum(vsp, p.velocity_max, out=vsp)
        maximum(vsp, self._neg_v_max, out=vsp)
        iv, lag, force = st.integrator, st.lag, st.applied
        ff = None
        if c.any_ff and force_ff is not None:
            ff = self._ff
            mul(force_ff, c.ff_scale, ff)
            add(iv, ff, iv)  # the feed-forward rides on the integrator for this cycle
        # Coulomb band of the velocity update; the external force shifts it (see the sub-step loop)
        coulomb_lo, coulomb_hi = c.neg_coulomb, c.coulomb
        if external_force is not None:
            coulomb_lo, coulomb_hi = self._clo, self._chi
            mul(external_force, c.scale, tmp)
            sub(c.neg_coulomb, tmp, coulomb_lo)
            sub(c.coulomb, tmp, coulomb_hi)

        # force window [lo, hi]: the voltage limit K (+-U - K v) / R at the velocity of the start of the cycle,
        # within the current limit on both sides (overdriven beyond the no-load speed, the drive brakes, but with
        # no more than the limit current: uncontrolled regeneration through the diodes is not modelled)
        hi, lo = self._window_rows
        mul(c.emf_c, v, tmp)
        sub(c.emf_a, tmp, hi)
        sub(c.neg_emf_a, tmp, lo)
        minimum(self._window, c.fcap2, out=self._window)
        maximum(self._window, c.neg_fcap2, out=self._window)

        # velocity loop (4 kHz), current loop and plant; all forces as velocity increments per sub-step
        ev, w, vsum, ok = self._ev, self._w, self._vsum, self._ok
        akp, aki, beta, damping = c.akp, c.aki, c.beta, c.damping
        vsum.fill(0.0)
        for _ in range(p.substeps):
            sub(vsp, v, ev)
            # current loop: first-order lag of the PI demand alpha (kp ev + I), then the limits
            mul(akp, ev, tmp)
            mul(lag, beta, lag)
            add(lag, tmp, lag)
            add(lag, iv, lag)
            minimum(lag, hi, out=force)
            maximum(force, lo, out=force)
            # PI integrator, frozen while the current is limited (anti-windup)
            equal(force, lag, ok)
            mul(aki, ev, tmp)
            mul(tmp, ok, tmp)
            add(iv, tmp, iv)
            # velocity, implicit in Coulomb and viscous friction: v' = (p - clip(p, -s F_c, s F_c)) / (1 + h b / M)
            # with p = v + s (F + F_ext); written with w = v + s F and the Coulomb band shifted by -s F_ext
            add(v, force, w)
            minimum(w, coulomb_hi, out=tmp)
            maximum(tmp, coulomb_lo, out=tmp)
            sub(w, tmp, v)
            mul(v, damping, v)
            add(vsum, v, vsum)
        if ff is not None:
            sub(iv, ff, iv)

        # position with the sub-steps' new velocities (semi-implicit Euler); end stops: clamp and stop
        xn = self._xn
        mul(vsum, c.h, tmp)
        add(x, tmp, xn)
        minimum(xn, p.position_max, out=x)
        maximum(x, p.position_min, out=x)
        equal(x, xn, ok)
        mul(v, ok, v)

        # winding temperature: exact first-order response to i^2 R over the cycle
        temp = st.temperature
        mul(force, force, tmp)
        mul(tmp, c.thermal_c1, tmp)
        add(tmp, c.thermal_c0, tmp)
        mul(temp, c.thermal_decay, temp)
        add(temp, tmp, temp)

        # status (row 0 ENABLED is set with the mode, row 1 SETPOINT_CLIPPED above)
        monitor = self._monitor_rows
        np.copyto(monitor[0], x)
        np.negative(x, monitor[1])
        np.abs(force, monitor[2])
        np.abs(vsp, monitor[3])
        np.abs(epos, monitor[4])
        np.greater_equal(self._monitor, c.thresholds, self._compared)
        np.not_equal(force, lag, flags[2])
        np.greater(flags[2], flags[5], flags[2])  # limited, but not by the current limit: by the voltage
        np.greater(temp, p.temperature_max, flags[8])
        st.cycles += 1
        mul(force, c.inv_scale, st.force)
        return ActuatorMeasurement(
            x.copy(),
            v.copy(),
            st.force.copy(),
            mul(st.force, self._inv_force_constant),
            temp.copy(),
            _STATUS_WEIGHTS.dot(self._flags_u8),
        )

    # --- outputs ----------------------------------------------------------------------------------------------

    def measure(self) -> ActuatorMeasurement:
        """The last readings again (fresh arrays), without stepping."""
        st = self.state
        return ActuatorMeasurement(
            st.position.copy(),
            st.velocity.copy(),
            st.force.copy(),
            st.force * self._inv_force_constant,
            st.temperature.copy(),
            _STATUS_WEIGHTS.dot(self._flags_u8),
        )

    @property
    def velocity_integral(self) -> FloatArray:
        """The velocity-loop integrator in N or Nm (zero before the first step)."""
        if self._coef is None:
            return np.zeros(self.params.num)
        return self.state.integrator / (self._coef.alpha * self._coef.scale)

    # --- modes and per-cycle coefficients ------------------------------------------------------------------------

    def _set_mode(self, mode: int | ArrayLike, dt: float) -> _Coefficients:
        """Apply a (possibly new) mode vector and cycle length: latch HOLD, reset integrators, rebuild coefficients."""
        modes = mode if type(mode) is np.ndarray else np.asarray(mode)
        if modes.dtype is not _INT8 or modes.shape != self._shape:
            modes = np.broadcast_to(modes, self._shape).astype(np.int8)
        key = modes.tobytes()
        old_coef = self._coef
        if key == self._mode_key and old_coef is not None and dt == old_coef.dt:
            return old_coef
        if not (0.0 < dt <= self.params.max_dt):
            msg = f"step: dt must be in (0, {self.params.max_dt:.4g}] s, got {dt}"
            raise ValueError(msg)
        if modes.min() < CommandMode.OFF or modes.max() > CommandMode.POSITION_FF:
            msg = f"step: modes must be in {[int(m) for m in CommandMode]}, got {sorted(set(modes.tolist()))}"
            raise ValueError(msg)
        st = self.state
        coef = self._coefficients(dt, modes)
        if old_coef is not None and dt != old_coef.dt:  # keep the physical meaning of the scaled state
            for scaled, factor in (
                (st.lag, coef.scale / old_coef.scale),
                (st.applied, coef.scale / old_coef.scale),
                (st.integrator, coef.alpha * coef.scale / (old_coef.alpha * old_coef.scale)),
            ):
                np.multiply(scaled, factor, out=scaled)
        old = st.mode
        changed = modes != old
        entering_hold = changed & (modes == CommandMode.HOLD)
        st.hold_position[entering_hold] = st.position[entering_hold]
        reset = changed & ((old == CommandMode.OFF) | (modes == CommandMode.OFF))  # switching the power stage on or off
        for values in (st.integrator, st.position_integral, st.lag, st.applied, st.force):
            values[reset] = 0.0
        st.mode = modes.copy()
        self._flags[0] = modes != CommandMode.OFF
        self._mode_key = key
        self._coef = coef
        return coef

    def _coefficients(self, dt: float, modes: npt.NDArray[np.int8]) -> _Coefficients:
        p = self.params
        h = dt / p.substeps
        en = (modes != CommandMode.OFF).astype(np.float64)
        on = en > 0
        ff_gain = (modes == CommandMode.POSITION_FF).astype(np.float64)
        hold = modes == CommandMode.HOLD
        s = h / p.inertia
        alpha = -np.expm1(-h / p.current_time_constant)
        emf_a = p.force_constant * p.bus_voltage / p.resistance * s * en
        fcap = p.force_max * s * en
        coulomb = p.coulomb * s
        decay = np.exp(-dt / p.thermal_time_constant)
        thresholds = np.stack(
            [
                p.position_max,
                -p.position_min,
                np.where(on, fcap * (1.0 - 1e-9), np.inf),
                p.velocity_max,
                np.where(on, p.following_error_max, np.inf),
            ]
        )
        return _Coefficients(
            dt=dt,
            scale=s,
            alpha=alpha,
            beta=1.0 - alpha,
            kp_pos=p.kp_position * en,
            ki_pos_dt=p.ki_position * dt * en,
            ff_gain=ff_gain,
            ff_scale=ff_gain * alpha * s,
            akp=alpha * p.kp_velocity * s * en,
            aki=alpha * p.ki_velocity * h * s * en,
            emf_a=emf_a,
            neg_emf_a=-emf_a,
            emf_c=p.force_constant**2 / p.resistance * s * en,
            fcap2=np.stack([fcap, fcap]),
            neg_fcap2=np.stack([-fcap, -fcap]),
            coulomb=coulomb,
            neg_coulomb=-coulomb,
            damping=1.0 / (1.0 + h * p.viscous / p.inertia),
            h=np.full(p.num, h),
            inv_scale=1.0 / s,
            thresholds=thresholds,
            thermal_decay=decay,
            thermal_c0=(1.0 - decay) * p.ambient_temperature,
            thermal_c1=(1.0 - decay) * p.resistance * p.thermal_resistance / (p.force_constant * s) ** 2,
            hold=hold,
            any_hold=bool(hold.any()),
            any_ff=bool(ff_gain.any()),
        )


# ----------------------------------------------------------------------------------------------------------------
# Cost and a summary for people


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
