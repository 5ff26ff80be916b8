"""The stabilizer's parameter spec: 1 kHz by default, the 5 ms stale-state rule, correction off."""

from __future__ import annotations

from rh5_msgs_py.parameters import load_spec


def test_defaults_follow_the_design() -> None:
    specs = {s.name: s for s in load_spec("rh5_joint_stabilizer", "params/stabilizer.yaml")}
    assert specs["rate_hz"].default == 1000.0
    assert specs["state_timeout_s"].default == 0.005
    assert specs["balance_correction"].default is False
    assert specs["state_timeout_s"].check(-1.0) != ""
