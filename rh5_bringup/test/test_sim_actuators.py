"""The simulated actuators and their board control: step and sine tracking, limits, modes, determinism, cost.

All 32 actuators run together (one vectorised bank) in every test; numbers in the bounds are derived in the
docstrings from the parameters (rh5_bringup/sim/actuator_params.yaml), not tuned to the results.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np
import pytest

from rh5_bringup.hardware.ndlcom.payloads import CommandMode
from rh5_bringup.sim.actuator_model import NOMINAL_DT, ActuatorParams, default_params
from rh5_bringup.sim.actuators import ActuatorBank, ActuatorFlags, ActuatorMeasurement
from rh5_msgs_py.names import ACTUATOR_NAMES, LINEAR_ACTUATOR_NAMES

DT = NOMINAL_DT
SINE_OMEGA = 2.0 * math.pi * 0.5  # 0.5 Hz


@pytest.fixture(scope="module")
def params() -> ActuatorParams:
    return default_params()


def mid_stroke(p: ActuatorParams) -> np.ndarray:
    return 0.5 * (p.position_min + p.position_max)


def run(bank: ActuatorBank, steps: int, mode: int, setpoint=None, **kwargs) -> list[ActuatorMeasurement]:
    """``steps`` cycles with constant commands."""
    return [bank.step(DT, mode, setpoint, **kwargs) for _ in range(steps)]


def stack(measurements: list[ActuatorMeasurement], field: str) -> np.ndarray:
    return np.array([getattr(m, field) for m in measurements])


# ---- parameters ---------------------------------------------------------------------------------------------------


def test_default_params_follow_the_limits_and_types(params: ActuatorParams) -> None:
    """The current limit makes the force limit, the no-load speed is the paper's max velocity, types as in names."""
    assert params.names == ACTUATOR_NAMES
    assert [n for n, lin in zip(params.names, params.linear, strict=True) if lin] == list(LINEAR_ACTUATOR_NAMES)
    np.testing.assert_allclose(params.force_constant * params.current_max, params.force_max, rtol=1e-12)
    np.testing.assert_allclose(params.force_constant * params.velocity_max, params.bus_voltage, rtol=1e-12)
    counts = {t: len(params.indices(t)) for t in params.type_names()}
    assert counts == {
        "torso": 2,
        "elbow": 3,
        "head": 3,
        "shoulder": 8,
        "shoulder2": 2,
        "wrist_roll": 2,
        "wrist": 4,
        "hip3": 2,
        "knee": 2,
        "ankle": 4,
    }
    knee = params.indices("knee")[0]  # paper: 5845 N, 140 mm/s, stroke 273-391 mm
    assert (params.force_max[knee], params.velocity_max[knee]) == (5845.0, 0.14)
    assert (params.position_min[knee], params.position_max[knee]) == (0.273, 0.391)
    assert params.max_dt >= DT
    assert np.all(params.current_max * params.resistance < params.bus_voltage)  # I_max reachable at standstill


def test_params_reject_inconsistent_values(params: ActuatorParams) -> None:
    with pytest.raises(ValueError, match="force_max != force_constant"):
        dataclasses.replace(params, current_max=params.current_max * 1.1)
    with pytest.raises(ValueError, match="unstable"):
        dataclasses.replace(params, kp_velocity=params.kp_velocity * 20)
    with pytest.raises(ValueError, match="does not fit"):
        dataclasses.replace(params, coulomb=np.ones(3))


# ---- step response ------------------------------------------------------------------------------------------------


def settle_bound(p: ActuatorParams, step: np.ndarray) -> np.ndarray:
    """Upper bound [s] on the 2 % settling time of a step, assembled from the physics of the cascade.

    Slew at (at least 95 % of) top speed, plus the time lost accelerating at (F_max - F_c) / M and braking along
    the position loop's braking curve, plus the exponential tail of the P loop from the whole step down to 2 %
    (ln 50 / kp), plus 5 ms for sampling, the velocity loop and the current lag.
    """
    accelerate = (p.force_max - p.coulomb) / p.inertia
    top = 0.95 * p.velocity_max
    return np.abs(step) / top + top / accelerate + top / p.braking_acceleration + math.log(50) / p.kp_position + 5e-3


@pytest.mark.parametrize(("start", "size"), [(0.5, 0.002), (0.5, 0.1), (0.7, -0.4)])
def test_step_response_settles_without_overshoot(params: ActuatorParams, start: float, size: float) -> None:
    """Steps of 0.2 % (linear cascade), 10 % and 40 % (velocity and force saturated) of the stroke.

    Overshoot stays below 0.5 % of the step: the linear cascade (velocity PI zero at a quarter of its 120 Hz
    crossover, position loop at 20 Hz) has about 70 degrees of phase margin, and after a saturated slew the
    braking curve plans with 70 % of the force limit, so the deceleration always has 25 % of margin left.
    """
    p = params
    x0 = p.position_min + start * p.stroke
    step = size * p.stroke
    bank = ActuatorBank(p)
    bank.reset(x0)
    run(bank, 20, CommandMode.POSITION, x0)
    bound = settle_bound(p, step)
    x = stack(run(bank, int(bound.max() / DT) + 50, CommandMode.POSITION, x0 + step), "position")
    error = (x - x0 - step) / step  # -1 at the start, 0 on target, > 0 beyond
    assert error.max() <= 5e-3
    outside = np.abs(error) > 0.02
    settled_at = np.array([(np.flatnonzero(col)[-1] + 1) * DT if col.any() else 0.0 for col in outside.T])
    assert np.all(settled_at <= bound), [(ACTUATOR_NAMES[i], settled_at[i], bound[i]) for i in range(p.num)]
    assert np.all(np.abs(x[-1] - x0 - step) <= 1e-6 * p.stroke)


# ---- sine tracking and feed-forward ----------------------------------------------------------------------------------


class SineResult(NamedTuple):
    amplitude: np.ndarray
    rms: np.ndarray
    peak: np.ndarray
    max_velocity: np.ndarray
    max_force: np.ndarray


def sine_amplitude(p: ActuatorParams) -> np.ndarray:
    """20 % of the stroke, reduced where 0.5 Hz would then ask for more than 95 % of the speed limit.

    Only Shoulder1/3 and Hip1 (+-180 deg: 17.6 % of the stroke) and Shoulder2 (18 %) are reduced; the wrist
    actuators run at 91 % of their speed limit.
    """
    return np.minimum(0.2 * p.stroke, 0.95 * p.velocity_max / SINE_OMEGA)


def track_sine(p: ActuatorParams, mode: CommandMode, seconds: float = 3.0) -> SineResult:
    """Track x = mid + A sin(w t) from a consistent start; errors measured over the last 2 s (after 1 s)."""
    mid, amp, w = mid_stroke(p), sine_amplitude(p), SINE_OMEGA
    bank = ActuatorBank(p)
    bank.reset(mid, velocity=amp * w)
    errors, velocities, forces = [], [], []
    for k in range(round(seconds / DT)):
        t = k * DT
        s, c = math.sin(w * t), math.cos(w * t)
        v_ref = amp * w * c
        force_ff = p.inertia * (-amp * w * w * s) + p.viscous * v_ref  # inertia and viscous friction of the model
        m = bank.step(DT, mode, mid + amp * s, velocity_ff=v_ref, force_ff=force_ff)
        if t + DT >= 1.0:
            errors.append(m.position - (mid + amp * math.sin(w * (t + DT))))
        velocities.append(m.velocity)
        forces.append(m.force)
    e = np.array(errors)
    return SineResult(
        amp,
        np.sqrt(np.mean(e**2, axis=0)),
        np.abs(e).max(axis=0),
        np.abs(velocities).max(axis=0),
        np.abs(forces).max(axis=0),
    )


@pytest.fixture(scope="module")
def sine_runs(params: ActuatorParams) -> dict[CommandMode, SineResult]:
    return {mode: track_sine(params, mode) for mode in (CommandMode.POSITION, CommandMode.POSITION_FF)}


def test_sine_is_tracked_with_feed_forward(params: ActuatorParams, sine_runs: dict[CommandMode, SineResult]) -> None:
    """POSITION_FF: RMS error below 0.05 % and peak error below 0.3 % of the amplitude.

    What is left is what the feed-forward does not know: Coulomb friction, which the velocity integrator has to
    rebuild at every reversal (the peak error sits there), and one sub-step of current-loop lag.
    """
    result = sine_runs[CommandMode.POSITION_FF]
    assert np.all(result.rms <= 5e-4 * result.amplitude)
    assert np.all(result.peak <= 3e-3 * result.amplitude)
    assert np.all(result.max_velocity <= params.velocity_max)
    assert np.all(result.max_force <= params.force_max)


def test_sine_is_tracked_in_position_mode(params: ActuatorParams, sine_runs: dict[CommandMode, SineResult]) -> None:
    """POSITION (P position loop, no feed-forward): the peak error is the velocity lag v / kp of a type-1 loop.

    v_peak / kp at least, at most v_peak^2 / (2 a_brake) where the braking curve limits the feedback (fast
    rotary joints, wrist), with 10 % for the velocity loop's own lag.
    """
    p, result = params, sine_runs[CommandMode.POSITION]
    v_peak = result.amplitude * SINE_OMEGA
    lag = v_peak / p.kp_position
    upper = 1.1 * np.maximum(lag, v_peak**2 / (2 * p.braking_acceleration))
    assert np.all(result.peak >= 0.95 * lag)
    assert np.all(result.peak <= upper)


def test_feed_forward_reduces_the_tracking_error(sine_runs: dict[CommandMode, SineResult]) -> None:
    """Velocity and force feed-forward cut the RMS error of the sine at least 50-fold (typically ~1000-fold)."""
    assert np.all(sine_runs[CommandMode.POSITION_FF].rms <= 0.02 * sine_runs[CommandMode.POSITION].rms)


# ---- limits -------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("load_fraction", [0.0, 0.3])
def test_velocity_never_exceeds_the_limit(params: ActuatorParams, load_fraction: float) -> None:
    """Full-stroke steps beyond both ends with 10x velocity and 2x force feed-forward, free or against a load.

    The motor cannot push past its no-load speed (back-EMF = bus voltage), and the explicit back-EMF slope
    stays below 1 per cycle (``max_dt``), so the speed approaches the limit from below.
    """
    p = params
    bank = ActuatorBank(p)
    bank.reset(mid_stroke(p))
    seen = 0
    for k in range(1200):
        sign = 1.0 if (k // 300) % 2 else -1.0
        mode = CommandMode.POSITION_FF if k % 600 < 300 else CommandMode.POSITION
        setpoint = np.where(sign > 0, p.position_max, p.position_min) + sign * 0.1 * p.stroke
        m = bank.step(
            DT,
            mode,
            setpoint,
            velocity_ff=sign * 10 * p.velocity_max,
            force_ff=sign * 2 * p.force_max,
            external_force=-sign * load_fraction * p.force_max,
        )
        assert np.all(np.abs(m.velocity) <= p.velocity_max)
        seen |= int(np.bitwise_or.reduce(m.status))
    assert seen & ActuatorFlags.VELOCITY_LIMIT
    assert seen & ActuatorFlags.SETPOINT_CLIPPED


def test_force_saturates_against_an_overload(params: ActuatorParams) -> None:
    """A load of 1.5 x the force limit pushes the actuator back to its end stop; the motor force stays at the limit."""
    p = params
    mid = mid_stroke(p)
    bank = ActuatorBank(p)
    bank.reset(mid)
    run(bank, 10, CommandMode.POSITION, mid)
    history = run(bank, 400, CommandMode.POSITION, mid, external_force=-1.5 * p.force_max)
    force, status, x = stack(history, "force"), stack(history, "status"), stack(history, "position")
    assert np.all(np.abs(force) <= p.force_max * (1 + 1e-12))
    assert np.all(x[-1] < mid)
    np.testing.assert_allclose(force[5:], np.broadcast_to(p.force_max, force[5:].shape), rtol=1e-9)
    assert np.all(status[5:] & ActuatorFlags.CURRENT_LIMIT)
    np.testing.assert_array_equal(x[-1], p.position_min)  # pushed all the way back onto the end stop
    assert np.all(status[-1] & ActuatorFlags.AT_LIMIT)
    np.testing.assert_allclose(history[-1].current, p.current_max, rtol=1e-9)


def test_end_stops_hold(params: ActuatorParams) -> None:
    """Neither a setpoint beyond the stroke nor a load driving a free actuator outwards gets past the end stops."""
    p = params
    bank = ActuatorBank(p)
    bank.reset(mid_stroke(p))
    beyond = p.position_max + 0.2 * p.stroke
    history = run(bank, 1200, CommandMode.POSITION_FF, beyond, velocity_ff=p.velocity_max, force_ff=p.force_max)
    x = stack(history, "position")
    assert np.all(x <= p.position_max)
    np.testing.assert_array_equal(x[-1], p.position_max)
    assert np.all(history[-1].status & ActuatorFlags.SETPOINT_CLIPPED)
    assert np.all(history[-1].status & ActuatorFlags.AT_LIMIT)
    # power off and drive it outwards with half the force limit: inelastic stop, zero velocity on it
    history = run(bank, 600, CommandMode.OFF, external_force=-0.5 * p.force_max)
    x = stack(history, "position")
    assert np.all(x >= p.position_min)
    np.testing.assert_array_equal(x[-1], p.position_min)
    np.testing.assert_array_equal(history[-1].velocity, 0.0)
    assert np.all(history[-1].status & ActuatorFlags.AT_LIMIT)


# ---- modes --------------------------------------------------------------------------------------------------------


def test_hold_keeps_the_position_under_load(params: ActuatorParams) -> None:
    """HOLD latches the position measured on entry, ignores the setpoint, and stiffly rejects a 30 % load step.

    Peak deflection below 0.2 % of the stroke (0.2 mm on a knee): the 120 Hz velocity loop answers the load
    step within milliseconds; the velocity integrator then brings the position back (to within the Coulomb
    stiction band of the integrator, far below encoder resolution).
    """
    p = params
    x0 = p.position_min + 0.4 * p.stroke
    bank = ActuatorBank(p)
    bank.reset(x0)
    run(bank, 20, CommandMode.POSITION, x0)
    load = 0.3 * p.force_max * np.where(np.arange(p.num) % 2, 1.0, -1.0)
    history = run(bank, 500, CommandMode.HOLD, x0 + 0.1 * p.stroke, external_force=load)
    deviation = np.abs(stack(history, "position") - x0)
    assert np.all(deviation.max(axis=0) <= 2e-3 * p.stroke)
    assert np.all(deviation[-1] <= 1e-9 * p.stroke)
    # the motor holds the load (Coulomb friction takes at most F_c of it)
    assert np.all(np.abs(history[-1].force + load) <= p.coulomb * (1 + 1e-9))


def test_off_lets_the_load_move_the_actuator(params: ActuatorParams) -> None:
    """OFF: no current; a load above Coulomb friction accelerates the free actuator as F - F_c - b v = M a says.

    x(t) = (a / beta) (t - (1 - exp(-beta t)) / beta) with a = (F - F_c) / M and beta = b / M; 0.5 % tolerance
    for the semi-implicit 4 kHz integration. Below the Coulomb level it does not move at all.
    """
    p = params
    mid = mid_stroke(p)
    bank = ActuatorBank(p)
    bank.reset(mid)
    load = 0.2 * p.force_max
    history = run(bank, 50, CommandMode.OFF, external_force=load)
    t = 50 * DT
    a, beta = (load - p.coulomb) / p.inertia, p.viscous / p.inertia
    expected = a / beta * (t + np.expm1(-beta * t) / beta)
    np.testing.assert_allclose(history[-1].position - mid, expected, rtol=5e-3)
    np.testing.assert_array_equal(stack(history, "current"), 0.0)
    assert not np.any(stack(history, "status") & ActuatorFlags.ENABLED)
    bank.reset(mid)
    history = run(bank, 50, CommandMode.OFF, external_force=0.9 * p.coulomb)
    np.testing.assert_array_equal(history[-1].position, mid)


def test_switching_off_and_on_again(params: ActuatorParams) -> None:
    """Per-actuator modes; switching OFF drops the current at once; invalid modes and cycles are refused."""
    p = params
    mid = mid_stroke(p)
    bank = ActuatorBank(p)
    bank.reset(mid)
    modes = np.full(p.num, CommandMode.POSITION, dtype=np.int8)
    modes[::2] = CommandMode.OFF
    m = run(bank, 300, modes, mid + 0.05 * p.stroke)[-1]
    np.testing.assert_array_equal(m.position[::2], mid[::2])
    np.testing.assert_allclose(m.position[1::2], (mid + 0.05 * p.stroke)[1::2], rtol=0, atol=1e-6)
    assert np.all(m.status[1::2] & ActuatorFlags.ENABLED)
    assert not np.any(m.status[::2] & ActuatorFlags.ENABLED)
    m = bank.step(DT, CommandMode.OFF, external_force=0.1 * p.force_max)
    np.testing.assert_array_equal(m.force, 0.0)
    with pytest.raises(ValueError, match="modes must be"):
        bank.step(DT, 7, mid)
    with pytest.raises(ValueError, match="dt must be"):
        bank.step(5 * DT, CommandMode.POSITION, mid)


def test_a_shorter_cycle_keeps_the_state(params: ActuatorParams) -> None:
    """Changing dt rescales the internal (per-sub-step) state: force and integrator carry on unchanged."""
    p = params
    mid = mid_stroke(p)
    bank = ActuatorBank(p)
    bank.reset(mid)
    load = 0.4 * p.force_max
    before = run(bank, 300, CommandMode.POSITION, mid, external_force=load)[-1]
    integral = bank.velocity_integral
    after = bank.step(DT / 2, CommandMode.POSITION, mid, external_force=load)
    np.testing.assert_allclose(after.force, before.force, rtol=1e-9)
    np.testing.assert_allclose(bank.velocity_integral, integral, rtol=1e-9)


def test_winding_heats_with_i2r(params: ActuatorParams) -> None:
    """Holding 80 % of the force limit heats the winding as T_amb + I^2 R R_th (1 - exp(-t / tau))."""
    p = params
    mid = mid_stroke(p)
    bank = ActuatorBank(p)
    bank.reset(mid)
    load = 0.8 * p.force_max
    run(bank, 300, CommandMode.POSITION, mid, external_force=load)  # settle: the motor now carries the load
    t0 = bank.state.temperature.copy()
    m = run(bank, 1000, CommandMode.POSITION, mid, external_force=load)[-1]
    power = m.current**2 * p.resistance
    settled = p.ambient_temperature + power * p.thermal_resistance
    expected = settled + (t0 - settled) * np.exp(-1.0 / p.thermal_time_constant)
    np.testing.assert_allclose(m.temperature, expected, rtol=1e-3)
    assert np.all(m.temperature > p.ambient_temperature)


# ---- determinism and cost -------------------------------------------------------------------------------------------


def test_same_inputs_give_the_same_outputs(params: ActuatorParams) -> None:
    """Bit-identical runs for the same command sequence (random but seeded modes, setpoints, loads)."""
    p = params
    rng = np.random.default_rng(5)
    commands = [
        (
            rng.integers(0, 4, p.num).astype(np.int8) if k % 97 == 0 else None,
            p.position_min + rng.uniform(0, 1, p.num) * p.stroke,
            rng.normal(0, 0.3, p.num) * p.velocity_max,
            rng.normal(0, 0.3, p.num) * p.force_max,
            rng.normal(0, 0.3, p.num) * p.force_max,
        )
        for k in range(400)
    ]

    def replay() -> list[ActuatorMeasurement]:
        bank = ActuatorBank(p)
        bank.reset(mid_stroke(p))
        out, mode = [], CommandMode.POSITION
        for new_mode, setpoint, velocity_ff, force_ff, external_force in commands:
            mode = mode if new_mode is None else new_mode
            out.append(
                bank.step(DT, mode, setpoint, velocity_ff=velocity_ff, force_ff=force_ff, external_force=external_force)
            )
        return out

    first, second = replay(), replay()
    for a, b in zip(first, second, strict=True):
        for field in ActuatorMeasurement._fields:
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
