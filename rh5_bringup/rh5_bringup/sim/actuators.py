"""Vectorised model of the 32 RH5 actuators and their board control, for the simulated hardware at 1 kHz.

Each board of RH5 runs a cascade of current (32 kHz), velocity (4 kHz) and position (1 kHz) loops with
velocity and current feed-forward inputs (paper, "Decentralized Actuator-Level Controllers"). This module
emulates all 32 actuator coordinates (names.ACTUATOR_NAMES order; lengths in m and forces in N for the 14
linear actuators, angles in rad and torques in Nm for the rotary drives) as arrays of shape (32,), split
Crocoddyl-style into immutable parameters (`ActuatorParams`, built by `default_params`) and mutable state
(`ActuatorState`), both in :mod:`rh5_bringup.sim.actuator_model` and both held by an `ActuatorBank` (here) that is
``reset`` once and then ``step``-ped every 1 ms.

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

from enum import IntFlag
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from rh5_bringup.hardware.ndlcom.payloads import CommandMode
from rh5_bringup.sim.actuator_model import ActuatorParams, ActuatorState, default_params, read_only
from rh5_msgs_py.array_types import FloatArray

ArrayLike = npt.ArrayLike


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
        self._neg_v_max = read_only(-p.velocity_max)
        self._two_a_brake = read_only(2.0 * p.braking_acceleration)
        self._inv_force_constant = read_only(1.0 / p.force_constant)
        self._zeros = read_only(np.zeros(n))
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
