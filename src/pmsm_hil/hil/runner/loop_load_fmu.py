"""The native loop's load FMU (src/pmsm_hil/hil/load_fmu): opened and initialised at the start speed before the run, its
nl_fmu_t handed to the C loop (nl_config_t.load_fmu), its failure worded, closed after the run."""

from __future__ import annotations

from typing import Any

from pmsm_hil.hil.mechanics import RPM_TO_RAD_S
from pmsm_hil.hil.runner.load_fmu_session import LoadFmuSession
from pmsm_hil.hil.runner.run_config import RunConfig


def open_load_fmu(cfg: RunConfig, ffi: Any, lib: Any, c: Any) -> LoadFmuSession | None:
    """The run's load FMU instance set into nl_config_t `c` (None and a NULL pointer without one)."""
    model = cfg.load_fmu_model
    if model is None:
        c.load_fmu = ffi.NULL
        return None
    session = LoadFmuSession(model, ffi, lib, cfg.scenario.start_speed_rpm * RPM_TO_RAD_S, ts_s=cfg.ts_s,
                             timeout_s=cfg.step_timeout_s)
    c.load_fmu = session.fmu
    return session


def load_fmu_failed(session: LoadFmuSession | None, res: Any, lib: Any) -> str | None:
    """The end reason when the C loop ended because the load FMU failed (None otherwise)."""
    if session is None or int(res.end) != lib.NL_END_PLANT_ERROR or int(res.plant_rc) != lib.NL_PLANT_E_LOAD_FMU:
        return None
    return session.failure()
