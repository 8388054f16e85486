"""The groups of a run's configuration: which `RunConfig` field belongs to which part of the run, and the
read-only group views (`cfg.timing.ts_s`, `cfg.target_link.link_spec`, ...). `RunConfig` keeps one flat set of
keyword arguments (what scripts and `dataclasses.replace` use); the groups say how they belong together, as the
C loop's configuration does."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.hil.load_fmu.spec import LoadFmuSpec
from pmsm_hil.hil.runner.scenario import Scenario
from pmsm_hil.protocol.links.spec import LinkSpec

if TYPE_CHECKING:
    from pmsm_hil.hil.runner.run_config import RunConfig

#: group → the RunConfig fields it holds (every field in exactly one group; tests/runner/test_run_inputs.py).
#: machine: `cfg.machine` (the motor with its kind's descriptor); sensors: `cfg.sensors` and the noise seed
GROUPS: dict[str, tuple[str, ...]] = {
    "machine": ("motor",),
    "operation": ("scenario", "load_fmu"),
    "target_link": ("target", "link", "link_spec", "controller", "controller_params", "faults", "sil_in_process",
                    "mcu_clock_hz", "board", "tolerate", "watchdog_periods", "lockstep_timeout_s", "host_stall_limit_s",
                    "step_timeout_s"),
    "timing": ("ts_s", "mode", "loop", "pwm_update", "adc_delay_s", "miss_policy", "overrun_threshold_s",
               "rt_priority", "cpu", "cpu_dma_latency_us"),
    "sensors": ("sensors", "seed"),
    "outputs": ("out_dir", "log_trace", "trace_dt_s", "verbose"),
}


def group_of(cfg: RunConfig, names: tuple[str, ...]) -> dict[str, Any]:
    """The values of the fields `names` of `cfg`."""
    return {name: getattr(cfg, name) for name in names}


@dataclass(frozen=True, slots=True)
class OperationGroup:
    """Scenario and load: the operating point, its profiles and window; the load FMU replacing the scenario's
    load torque (None: the scenario's)."""

    scenario: Scenario
    load_fmu: LoadFmuSpec | None


@dataclass(frozen=True, slots=True)
class TargetLinkGroup:
    """Target and link: who runs the controller (`target`), the link SPEC and its parsed form, the controller and
    its parameters, injected link faults, the DUT contract (tolerate, watchdog) and the waits for a Command [s]."""

    target: str
    link: str
    link_spec: LinkSpec
    controller: str
    controller_params: dict[str, float]
    faults: str
    sil_in_process: bool
    mcu_clock_hz: float
    board: str | None
    tolerate: int
    watchdog_periods: int
    lockstep_timeout_s: float
    host_stall_limit_s: float
    step_timeout_s: float

    @property
    def target_kind(self) -> str:
        """auto, inproc, spawn, external, sil, qemu or stm32g4."""
        return self.target.partition(":")[0]


@dataclass(frozen=True, slots=True)
class TimingGroup:
    """Timing and real time: control period [s], lockstep or real time, the period loop, PWM update and ADC
    instant [s]; in real time the miss policy, overrun threshold [s], SCHED_FIFO priority, CPU and PM QoS [µs]."""

    ts_s: float
    mode: str
    loop: str
    pwm_update: str
    adc_delay_s: float
    miss_policy: str
    overrun_threshold_s: float | None
    rt_priority: int
    cpu: int | None
    cpu_dma_latency_us: int | None

    @property
    def ts_ns(self) -> int:
        """Control period [ns]."""
        return round(self.ts_s * 1e9)

    @property
    def adc_delay_ns(self) -> int:
        """The ADC instant after the period start [ns]."""
        return round(self.adc_delay_s * 1e9)

    @property
    def overrun_threshold_ns(self) -> int:
        """Real-time lateness [ns] above which a period start is an overrun (default Ts / 2)."""
        return round((self.ts_s / 2 if self.overrun_threshold_s is None else self.overrun_threshold_s) * 1e9)


@dataclass(frozen=True, slots=True)
class OutputGroup:
    """Outputs: the run directory (None: no log), the 2 µs plant trace and its step [s], the target console echo."""

    out_dir: Path | None
    log_trace: bool
    trace_dt_s: float
    verbose: bool


__all__ = ["GROUPS", "OperationGroup", "OutputGroup", "TargetLinkGroup", "TimingGroup", "group_of"]
