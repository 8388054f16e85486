"""Entity paths and the timeline of the dashboard recording (one place, shared by streamer and blueprint)."""

from __future__ import annotations

from typing import Final

APPLICATION_ID: Final = "pmsm_hil"
#: Timeline: simulated time of the period start [s] (a duration timeline).
TIMELINE: Final = "time"

TORQUE: Final = "/torque/actual"
TORQUE_REF: Final = "/torque/reference"
TORQUE_LOAD: Final = "/torque/load"
RIPPLE: Final = "/ripple/torque_rms"
CURRENTS: Final = ("/currents/i_a", "/currents/i_b", "/currents/i_c")
SPEED: Final = "/speed/actual"
SPEED_REF: Final = "/speed/reference"
AB_HEXAGON: Final = "/ab/hexagon"
AB_LIMIT: Final = "/ab/linear_limit"
AB_CANDIDATES: Final = "/ab/candidates"
AB_SELECTED: Final = "/ab/selected"
XY_HEXAGON: Final = "/xy/outline"
XY_SELECTED: Final = "/xy/selected"
EXEC_TIME: Final = "/timing/exec_time_us"
EXEC_HIST: Final = "/timing_histogram/exec_time"
FSW: Final = "/switching/f_av_khz"

#: Entities that get one row per control period (used by tests and `hil replay` to check counts).
PER_PERIOD: Final = (TORQUE, TORQUE_REF, TORQUE_LOAD, RIPPLE, *CURRENTS, SPEED, SPEED_REF, AB_CANDIDATES,
                     AB_SELECTED, EXEC_TIME, FSW)
