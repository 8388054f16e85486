"""Target conformance suite: one pytest test per rule of the protocol contract (docs/protocol.md "Target
behaviour", docs/runner.md "DUT contract"), each failing with the rule's name. A board vendor runs it against
their firmware::

    pytest --pyargs pmsm_hil.conformance --hil-target external:socketcan:can0 --hil-controller external

(`--hil-target inproc` / `spawn` check the reference firmware). Two sources of evidence: one closed-loop run
in speed mode with a speed step (every contract finding tolerated and counted per rule), and a probe
(`pmsm_hil.conformance.probe`) that drives the target period by period on a dyno plant with the Setpoints a run
never sends (torque mode, a disable while running, a gap in the measurements, an undefined mode, an
unassigned controller id).
"""

from __future__ import annotations

from pmsm_hil.hil.runner.contract import DURATIONS, DUTY, FRAME, MISSING, SEQUENCE, STATE_CODE

#: rule → what the target must do (the test of each rule fails with its name and this text)
RULES: dict[str, str] = {
    MISSING: "timing: exactly one Command per Measurement, within the lockstep timeout",
    SEQUENCE: "sequence echo: each Command echoes its Measurement's seq, no other seq, no second reply",
    STATE_CODE: "state codes of the machine only (0..2^legs − 1)",
    DURATIONS: "durations filling Ts exactly (mirrored: 2·(d0+…+d(n−2)) + d(n−1) = Ts), none negative",
    FRAME: "well-formed frames (length, values, parts that assemble)",
    DUTY: "duty-cycle Commands: one duty per leg of the machine, each 0..1 (never NaN)",
    "config_ack": "every ConfigParam acknowledged by a ConfigAck echoing the float32 value bit for bit, status 0",
    "setpoint_disabled": "while disabled, every Measurement answered with a full-period zero vector (on the virtual "
                         "board: or with every gate off, TIM1 MOE = 0)",
    "safe_state": "after a disabling Setpoint while running, the next Measurement already gets the zero vector (on "
                  "the virtual board: or every gate off)",
    "safe_stop": "every disabling Setpoint answered with a HeartbeatTarget in state idle within 500 ms (the "
                 "confirmed safe stop; a run's end included)",
    "watchdog": "after the host's watchdog (Measurements stop, a disabling Setpoint follows) the next Measurement, "
                "its seq jumped, gets the zero vector echoing the new seq (on the virtual board: or every gate off)",
    "speed_mode": "Setpoint mode 0: the speed follows the reference (rad/s) through the speed PI",
    "torque_mode": "Setpoint mode 1: the torque follows the reference (N·m)",
    "fault_mode": "an undefined Setpoint mode: FaultTarget code 5 invalid_config, detail = the mode",
    "fault_controller": "a controller id the firmware does not implement: FaultTarget code 6 not_implemented, "
                        "detail = the id",
}


def broken(rule: str, detail: str) -> str:
    """The failure message of `rule`: its name, what it requires, what the target did."""
    return f"conformance rule '{rule}' broken ({RULES[rule]}): {detail}"


__all__ = ["RULES", "broken"]
