"""Joint-space torque and velocity envelopes of the parallel joints, from the actuator table and our geometry.

``python -m rh5_hyrodyn_mapper.limits`` prints them beside the paper's joint table ("ROM of the RH5 humanoid robot in
its independent joint space"). Each parallel joint is swept over its ROM (the robot model's joint limits = the
paper's ROM, sign-adjusted) on its axis line: the other joint of a 2-DOF unit held at 0 (design/mechanisms.md 8.2).
With J = dl/dy, actuator force F and speed v (paper table "ROM of linear actuators"), and e_j the joint's unit vector:

* pure torque      tau_j = F / ||J^-T e_j||_inf  (the largest torque about j alone that no actuator force exceeds);
* F sum|J|         F * sum_i |J_ij|             (both actuators saturated, ignoring the coupled torque on the other
                                                  axis; equals the pure value where the arms are symmetric);
* pure speed       omega_j = v / ||J e_j||_inf   (the fastest motion about j alone that no actuator speed exceeds);
* per-actuator     v / |J_ij| over every actuator i (each actuator's own bound, ignoring the other's speed limit).
  The paper's velocity columns of ankle roll (386-726), torso roll (208-400) and wrist pitch (60-106 deg/s) are
  reproduced only by this optimistic bound.

Power bound (8.1): for any configuration tau_j * omega_j <= k F v (k actuators), since
1 = (J e)^T (J^-T e) <= k ||J e||_inf ||J^-T e||_inf. So the paper's tau_min * omega_max and tau_max * omega_min must
not exceed k F v, whatever configurations the extremes come from. A row whose printed (integer-rounded) numbers break
this bound even after rounding (each entry +-0.5 in its printed unit) cannot be satisfied by any geometry.
"""

from __future__ import annotations

import argparse
import functools
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rh5_hyrodyn_mapper.kinematics import build_submechanisms, load_geometry
from rh5_hyrodyn_mapper.model import joint_limits, load_parameters
from rh5_msgs_py.names import JOINT_INDEX

__all__ = ["EnvelopeRow", "format_table", "joint_envelopes", "main"]

SAMPLES = 4001  # points on each axis line (0.02 deg steps on a 90 deg ROM)

# Submechanism and actuator type of each paper row; the joint comes from rh5_parameters.yaml (limits.<joint>.paper),
# the left side stands for both (the right units are copies or mirror images).
_UNITS: dict[str, tuple[str, str]] = {
    "hip3": ("LLHip3", "hip3"),
    "knee": ("LLKnee", "knee"),
    "ankle_pitch": ("LLAnkle", "ankle"),
    "ankle_roll": ("LLAnkle", "ankle"),
    "torso_pitch": ("Body", "torso"),
    "torso_roll": ("Body", "torso"),
    "wrist_pitch": ("ALWrist", "wrist"),
    "wrist_yaw": ("ALWrist", "wrist"),
}


@dataclass(frozen=True)
class EnvelopeRow:
    """One paper row: its ROM, the paper's ranges, and the model's envelopes on the axis line (SI units)."""

    row: str
    joint: str
    submechanism: str
    actuators: int
    rom: tuple[float, float]
    paper_torque: tuple[float, float]
    paper_velocity: tuple[float, float]
    paper_stroke: tuple[float, float]
    force_max: float
    velocity_max: float
    stroke: tuple[float, float]
    torque: tuple[float, float]
    torque_sum: tuple[float, float]
    velocity: tuple[float, float]
    velocity_per_actuator: tuple[float, float]

    @property
    def power_bound(self) -> float:
        """k F v [W]."""
        return self.actuators * self.force_max * self.velocity_max

    @property
    def paper_power(self) -> float:
        """The larger of the paper's tau_min * omega_max and tau_max * omega_min [W]."""
        (t_lo, t_hi), (w_lo, w_hi) = self.paper_torque, self.paper_velocity
        return max(t_lo * w_hi, t_hi * w_lo)

    @property
    def paper_consistent(self) -> bool:
        """Whether the paper's numbers can meet tau * omega <= k F v within their printed rounding (+-0.5 unit)."""
        (t_lo, t_hi), (w_lo, w_hi) = self.paper_torque, self.paper_velocity
        dw = math.radians(0.5)  # deg/s entries
        product = max((t_lo - 0.5) * (w_hi - dw), (t_hi - 0.5) * (w_lo - dw))
        bound = self.actuators * (self.force_max + 0.5) * (self.velocity_max + 0.0005)  # N and mm/s entries
        return product <= bound

    @property
    def stroke_excess(self) -> float:
        """How far [m] the axis line over the ROM reaches beyond the actuator stroke (0 when it stays inside)."""
        return max(self.paper_stroke[0] - self.stroke[0], self.stroke[1] - self.paper_stroke[1], 0.0)

    def deviation(self, quantity: str) -> tuple[float, float]:
        """(model - paper) / paper in % for ``torque``, ``velocity`` or ``velocity_per_actuator``, (lo, hi)."""
        paper = self.paper_torque if quantity.startswith("torque") else self.paper_velocity
        model = getattr(self, quantity)
        return (100.0 * (model[0] / paper[0] - 1.0), 100.0 * (model[1] / paper[1] - 1.0))


def _line(model, index: int, rom: tuple[float, float]) -> dict[str, tuple[float, float]]:
    q = np.linspace(rom[0], rom[1], SAMPLES)
    y = np.zeros((SAMPLES, model.dof))
    y[:, index] = q
    jac = model.jacobian(y)
    lengths = model.inverse(y)
    column = np.abs(jac[:, :, index])  # |J_ij| over actuators i
    inv_t = np.linalg.inv(np.swapaxes(jac, -1, -2))  # J^-T
    force_per_torque = np.abs(inv_t[:, :, index]).max(axis=1)  # ||J^-T e_j||_inf
    speed_per_rate = column.max(axis=1)  # ||J e_j||_inf
    f, v = float(model.limits.force_max[0]), float(model.limits.velocity_max[0])
    torque = f / force_per_torque
    torque_sum = f * column.sum(axis=1)
    velocity = v / speed_per_rate
    per_actuator = v / column
    return {
        "stroke": (float(lengths.min()), float(lengths.max())),
        "torque": (float(torque.min()), float(torque.max())),
        "torque_sum": (float(torque_sum.min()), float(torque_sum.max())),
        "velocity": (float(velocity.min()), float(velocity.max())),
        "velocity_per_actuator": (float(per_actuator.min()), float(per_actuator.max())),
    }


@functools.cache
def _envelopes() -> tuple[EnvelopeRow, ...]:
    models = {m.name: m for m in build_submechanisms()}
    limits = joint_limits()
    paper_of = {joint: spec.get("paper") for joint, spec in load_parameters()["limits"].items()}
    actuator_types = load_geometry()["actuator_types"]
    rows = []
    for row, (unit, actuator_type) in _UNITS.items():
        model = models[unit]
        matches = [joint for joint in model.joints if paper_of[joint] == row]
        if len(matches) != 1:
            raise ValueError(f"paper row {row}: rh5_parameters.yaml maps it to {matches} among {unit}'s joints")
        joint = matches[0]
        j = JOINT_INDEX[joint]
        rom = (float(limits.position_lower[j]), float(limits.position_upper[j]))
        stroke = actuator_types[actuator_type]["stroke"]
        rows.append(
            EnvelopeRow(
                row=row,
                joint=joint,
                submechanism=unit,
                actuators=len(model.actuators),
                rom=rom,
                paper_torque=(float(limits.torque_range[j, 0]), float(limits.torque_range[j, 1])),
                paper_velocity=(float(limits.velocity_range[j, 0]), float(limits.velocity_range[j, 1])),
                paper_stroke=(float(stroke[0]), float(stroke[1])),
                force_max=float(actuator_types[actuator_type]["force_max"]),
                velocity_max=float(actuator_types[actuator_type]["velocity_max"]),
                **_line(model, model.joints.index(joint), rom),
            )
        )
    return tuple(rows)


def joint_envelopes() -> list[EnvelopeRow]:
    """The envelopes of every parallel joint row of the paper's table (hip3, knee, ankle, torso, wrist)."""
    return list(_envelopes())


def _range(values: Sequence[float], scale: float = 1.0, digits: int = 0, sep: str = "-") -> str:
    return f"{values[0] * scale:.{digits}f}{sep}{values[1] * scale:.{digits}f}"


def _pct(values: tuple[float, float]) -> str:
    return f"({values[0]:+.1f}/{values[1]:+.1f})"


def format_table(rows: Sequence[EnvelopeRow]) -> str:
    """The comparison as fixed-width text: torque Nm, speed deg/s, stroke mm, deviation from the paper in % (lo/hi)."""
    deg = math.degrees(1.0)
    header = (
        f"{'row':<12} {'joint':<13} {'ROM deg':>12}  {'stroke mm':>12} {'paper':>7}  "
        f"{'torque Nm':>9} {'pure (dev %)':>24}  {'speed deg/s':>11} {'pure (dev %)':>22} "
        f"{'per-act. (dev %)':>22}  {'tau*w/kFv W':>13}  verdict"
    )
    out = [
        "RH5 parallel joints on their axis lines (other joint at 0): the paper's joint table vs. our geometry and "
        "the paper's actuator table",
        "",
        header,
        "-" * len(header),
    ]
    for r in rows:
        out.append(
            f"{r.row:<12} {r.joint:<13} {_range(r.rom, deg, 1, '..'):>12}  "
            f"{_range(r.stroke, 1e3, 1) + ('!' if r.stroke_excess > 0.0005 else ' '):>12} "
            f"{_range(r.paper_stroke, 1e3):>7}  "
            f"{_range(r.paper_torque):>9} {_range(r.torque, 1.0, 1):>11} {_pct(r.deviation('torque')):>12}  "
            f"{_range(r.paper_velocity, deg):>11} {_range(r.velocity, deg):>9} {_pct(r.deviation('velocity')):>12} "
            f"{_range(r.velocity_per_actuator, deg):>9} {_pct(r.deviation('velocity_per_actuator')):>12}  "
            f"{r.paper_power:6.1f}/{r.power_bound:<6.1f}  "
            f"{'consistent' if r.paper_consistent else 'PAPER INCONSISTENT'}"
        )
    out += [
        "",
        "pure: tau = F/||J^-T e||_inf, omega = v/||J e||_inf; per-act.: v/|J_ij| of each actuator alone (optimistic).",
        "'!': the paper's ROM on this line needs actuator lengths outside the paper's stroke by more than its 0.5 mm "
        "rounding; beyond the stroke: "
        + "; ".join(f"{r.row} {r.stroke_excess * 1e3:.1f} mm" for r in rows if r.stroke_excess > 0.0),
        "F sum|J| torque (both actuators saturated, coupling ignored): "
        + "; ".join(f"{r.row} {_range(r.torque_sum, 1.0, 1)}" for r in rows if r.actuators > 1),
        "PAPER INCONSISTENT: the row's own tau_min*omega_max exceeds k F v even after +-0.5 rounding of every printed",
        "entry; no geometry can satisfy its torque and velocity columns together (tau*omega <= k F v everywhere).",
    ]
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the comparison table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    sys.stdout.write(format_table(joint_envelopes()) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
