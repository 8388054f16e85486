"""Record layouts exchanged between the runner, the run logger and the metrics (numpy structured dtypes).

Units are SI: time s, current A, torque N·m, speed rad/s (mechanical), angle rad (electrical).

`PERIOD_DTYPE`: one record per control period. `t` is the period start; the samples are measured at the
period start; `states`/`durations_ns` are the switching sequence applied during the period (the first
`n_states` entries are valid); `leg_transitions` counts the real gate transitions of all legs during the
period including the one at its start boundary, `boundary_transitions` those exactly at the period
start; `exec_time_ns` is the controller execution time, `exec_split_ns` its measure/reference/predict
split; `late`/`missed` are the real-time deadline flags. `narrow_pulses` counts leg pulses shorter than
T_lim = 2·T_dead + T_mpw requested in the period, `narrow_pulses_gated` those that reached the gate.
`mirror` = 1: the command was sent mirrored (`Command.mirror`): the plant applied states[0..n-1] then
states[n-2..0] with the same durations; `states`/`durations_ns` hold the slots as sent. Dual three-phase
runs fill `i_u`, `i_v`, `i_w` (second set) and `i_x`, `i_y` (harmonic subspace); three-phase runs leave
them NaN; `i_a`, `i_b`, `i_c` are the first set. `n_duties` = 3 or 6: the command applied was a duty-cycle
Command (`Command.duties`): `duties` holds its per-leg duties 0..1 (legs a, b, c, then u, v, w; NaN beyond
n_duties), `n_states` is 0 and the plant applied the carrier comparison of the duties (src/pmsm_hil/hil/pwm.py:
`duty_sequence` gives the applied states and durations); `n_duties` = 0: a switching-state Command, `duties` NaN
(0 in logs written before the field existed: only the first n_duties are valid).

`TRACE_DTYPE`: the plant's high-rate trace (one sample every ≤ 2 µs); `TRACE_DTYPE6` for six phases.

`FRAME_DTYPE`: one raw link frame; `direction` 0 = host→target, 1 = target→host; the first `length`
bytes of `data` are valid.
"""

from __future__ import annotations

from typing import Final

import numpy as np

PERIOD_DTYPE: Final = np.dtype(
    [
        ("t", "f8"),
        ("seq", "u4"),
        ("i_a", "f8"),
        ("i_b", "f8"),
        ("i_c", "f8"),
        ("i_d", "f8"),
        ("i_q", "f8"),
        ("torque", "f8"),
        ("omega_m", "f8"),
        ("theta_e", "f8"),
        ("torque_ref", "f8"),
        ("speed_ref", "f8"),
        ("load_torque", "f8"),
        ("n_states", "u1"),
        ("states", "u1", (3,)),
        ("durations_ns", "u4", (3,)),
        ("vector_id", "u1"),
        ("candidates", "u1"),
        ("exec_time_ns", "u4"),
        ("exec_split_ns", "u4", (3,)),
        ("leg_transitions", "u2"),
        ("boundary_transitions", "u2"),
        ("narrow_pulses", "u2"),
        ("late", "u1"),
        ("missed", "u1"),
        ("narrow_pulses_gated", "u2"),
        ("mirror", "u1"),
        ("i_u", "f8"),
        ("i_v", "f8"),
        ("i_w", "f8"),
        ("i_x", "f8"),
        ("i_y", "f8"),
        ("n_duties", "u1"),
        ("duties", "f8", (6,)),
    ]
)

TRACE_DTYPE: Final = np.dtype(
    [("t", "f8"), ("i_a", "f8"), ("i_b", "f8"), ("i_c", "f8"), ("torque", "f8"), ("omega_m", "f8")]
)

#: Trace of a dual three-phase run: both current sets and the x-y (harmonic subspace) currents.
TRACE_DTYPE6: Final = np.dtype(
    [("t", "f8"), ("i_a", "f8"), ("i_b", "f8"), ("i_c", "f8"), ("i_u", "f8"), ("i_v", "f8"), ("i_w", "f8"),
     ("torque", "f8"), ("omega_m", "f8"), ("i_x", "f8"), ("i_y", "f8")]
)



def trace_dtype(names: tuple[str, ...]) -> np.dtype:
    """Trace record dtype with these float64 fields (the layouts above, or a machine kind's own)."""
    return np.dtype([(name, "f8") for name in names])


FRAME_DTYPE: Final = np.dtype(
    [
        ("t", "f8"),
        ("seq", "u4"),
        ("direction", "u1"),
        ("arbitration_id", "u4"),
        ("is_fd", "u1"),
        ("length", "u1"),
        ("data", "u1", (64,)),
    ]
)

#: One injected link fault (`--fault`): run time t [s], period index, direction (0 host→target, 1
#: target→host), kind (index into FAULT_KINDS), the frame's arbitration id.
FAULT_DTYPE: Final = np.dtype([("t", "f8"), ("seq", "u4"), ("direction", "u1"), ("kind", "u1"),
                               ("arbitration_id", "u4")])
FAULT_KINDS: Final = ("drop", "dup", "corrupt", "delay", "reorder", "silence")

DIRECTION_HOST_TO_TARGET: Final = 0
DIRECTION_TARGET_TO_HOST: Final = 1

__all__ = [
    "DIRECTION_HOST_TO_TARGET",
    "DIRECTION_TARGET_TO_HOST",
    "FAULT_DTYPE",
    "FAULT_KINDS",
    "FRAME_DTYPE",
    "PERIOD_DTYPE",
    "TRACE_DTYPE",
    "TRACE_DTYPE6",
    "trace_dtype",
]
