"""The native loop's load FMU (src/pmsm_hil/hil/load_fmu): opened and initialised at the start speed before the run, its
nl_fmu_t handed to the C loop (nl_operation_cfg_t.load_fmu), its failure worded, closed after the run; an ending before
the first period (its process crashed or hung while initialising, or Ctrl-C/SIGTERM then) as an outcome with the
target disabled."""

from __future__ import annotations

from typing import Any

import numpy as np

from pmsm_hil.hil.load_fmu.errors import LoadFmuCrashError
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S
from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.load_fmu_session import LoadFmuSession
from pmsm_hil.hil.runner.loop_outcome import LoopOutcome
from pmsm_hil.hil.runner.recorder import frame_records, period_records
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.run_metadata import tap_setup_frames
from pmsm_hil.hil.runner.safe_stop import disable_and_confirm, settle_ending
from pmsm_hil.hil.runner.target_client import TargetClient, TargetError
from pmsm_hil.hil.runner.target_time import TargetTime
from pmsm_hil.protocol.errors import LinkError


def open_load_fmu(cfg: RunConfig, ffi: Any, lib: Any, c: Any) -> LoadFmuSession | None:
    """The run's load FMU instance set into nl_config_t `c` (None and a NULL pointer without one)."""
    model = cfg.load_fmu_model
    if model is None:
        c.operation.load_fmu = ffi.NULL
        return None
    session = LoadFmuSession(model, ffi, lib, cfg.scenario.start_speed_rpm * RPM_TO_RAD_S, ts_s=cfg.ts_s,
                             timeout_s=cfg.step_timeout_s)
    c.operation.load_fmu = session.fmu
    return session


def load_fmu_failed(session: LoadFmuSession | None, res: Any, lib: Any) -> str | None:
    """The end reason when the C loop ended because the load FMU failed (None otherwise)."""
    if session is None or int(res.end) != lib.NL_END_PLANT_ERROR or int(res.plant_rc) != lib.NL_PLANT_E_LOAD_FMU:
        return None
    return session.failure()


def ended_while_initialising(cfg: RunConfig, client: TargetClient, controller_id: int, logger: Any,
                             cause: BaseException, clock: TargetTime | None = None) -> LoopOutcome:
    """The outcome of a run that ended before its first period while the load FMU was initialised: its process
    crashed, exited or hung (`LoadFmuCrashError`: exit 3 naming it) or Ctrl-C/SIGTERM (exit 130). Nothing was
    enabled yet; the disabling Setpoint is still sent and its confirmation awaited (logged in `logger`'s MCAP),
    so a target on a real link ends disabled whatever the FMU did (`clock`: the target's own time, the safe stop's
    timeout counts it)."""
    if isinstance(cause, LoadFmuCrashError):
        code, reason = EndCode.SAFETY_STOP, f"{cause}; the run did not start, target disabled"
    else:
        code, reason = EndCode.INTERRUPTED, ("interrupted (Ctrl-C or SIGTERM) while initialising the load FMU, "
                                             "before the run started; target disabled")
    out = LoopOutcome(period_records(), frame_records(), np.zeros(0, cfg.machine.layout.trace_dtype), 0,
                      end_reason=reason, end_code=int(code), safe_state=True)
    out.load_fmu = cause.metrics if isinstance(cause, LoadFmuCrashError) else None
    try:
        with tap_setup_frames(client, logger):
            settle_ending(out, disable_and_confirm(client, controller_id, clock=clock,
                                                   stall_limit_s=cfg.host_stall_limit_s))
    except (LinkError, TargetError):  # the target is gone too
        out.target_disabled = False
    return out
