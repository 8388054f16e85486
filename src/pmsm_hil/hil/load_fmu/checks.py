"""The run-level checks of a load FMU (`RunConfig` calls them): the FMU read and checked once per file
version, a loop and mechanics that can apply it."""

from __future__ import annotations

import functools
from typing import Protocol

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.load_fmu.description import LoadFmuModel, read_load_fmu
from pmsm_hil.hil.load_fmu.spec import LoadFmuSpec


class _RunLike(Protocol):
    """What the checks read of a RunConfig."""

    @property
    def loop(self) -> str: ...

    @property
    def load_fmu(self) -> LoadFmuSpec | None: ...

    @property
    def scenario(self) -> _ScenarioLike: ...


class _ScenarioLike(Protocol):
    @property
    def mechanics(self) -> str: ...


@functools.lru_cache(maxsize=16)
def _read(spec: LoadFmuSpec, mtime_ns: int, size: int) -> LoadFmuModel:
    return read_load_fmu(spec)


def read_load_fmu_cached(spec: LoadFmuSpec) -> LoadFmuModel:
    """`read_load_fmu`, once per spec and file version (a sweep's runs share one read)."""
    try:
        st = spec.path.stat()
    except OSError:
        return read_load_fmu(spec)  # its own one-line error
    return _read(spec, st.st_mtime_ns, st.st_size)


def check_load_fmu(cfg: _RunLike) -> None:
    """ParameterError / LoadFmuError when the run cannot apply its load FMU."""
    if cfg.load_fmu is None:
        return
    if cfg.loop == "python":
        raise ParameterError("--load-fmu: a load FMU runs in the C loop only (--loop python is the test suite's "
                             "reference loop)")
    if cfg.scenario.mechanics != "inertia":
        raise ParameterError(f"--load-fmu: the scenario's mechanics is '{cfg.scenario.mechanics}' (speed held by the "
                             "dyno); a load FMU needs mechanics = \"inertia\"")
    read_load_fmu_cached(cfg.load_fmu)
