"""What a run of the period loop produced (`LoopOutcome`) and what consumes its blocks (`BlockSink`): shared by
the C loop's runner (loop.py) and the test suite's reference loop (tests/oracle/closed_loop.py)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from pmsm_hil.hil.metrics.lateness import LatenessStats
from pmsm_hil.hil.runner.contract import EndCode, Violation
from pmsm_hil.hil.runner.recorder import ByteRecords
from pmsm_hil.hil.runner.safe_stop import SafeStop


@dataclass(slots=True)
class LoopOutcome:
    """What the loop produced: records, counters and how it ended.

    `periods` keeps every period record for runs of up to `KEEP_PERIODS_MAX` periods (longer runs stream
    them to the block sink only); `frames` are streamed to the sink, never kept; `trace` is the end of the
    metrics-window trace (the runner sets it: the span the THD was computed over)."""

    periods: ByteRecords
    frames: ByteRecords
    trace: npt.NDArray[np.void]
    window_start_period: int
    completed_periods: int = 0
    #: wall time of the whole run [s]: start-up (enabling Setpoint, real-time set-up such as `mlockall`),
    #: the periods, the safe stop
    wall_time_s: float = 0.0
    #: wall time of the periods alone [s]: from the first period's scheduled start to the end of the loop
    #: (in real time, n·Ts plus the lateness of the last period when nothing started late)
    paced_time_s: float = 0.0
    deadline_misses: int = 0
    late_commands: int = 0
    lost_commands: int = 0
    #: real time: lateness of the period starts not yet folded into `lateness_us` (at most one block) [ns]
    lateness_ns: list[int] = field(default_factory=list)
    #: real time: lateness of every period start [µs] (quantiles within 0.39 %, in fixed memory: metrics/lateness.py)
    lateness_us: LatenessStats = field(default_factory=LatenessStats)
    #: real time, the C loop: period starts per 1 µs lateness bin [i, i+1) µs, the last bin open-ended (counted
    #: in C per period, src/pmsm_hil/hil/runner/c/loop_rt.c nl_late_count); None for the reference loop and lockstep
    #: runs
    lateness_hist_1us: npt.NDArray[np.int64] | None = None
    #: the C loop: times it waited for its consumer (the drain to metrics and the logger) to hand a slot back
    ring_waits: int = 0
    end_reason: str = "completed"
    #: how the run ended (`EndCode`: the exit code of `hil run`)
    end_code: int = EndCode.COMPLETED
    safe_state: bool = False
    #: the disabling Setpoint was sent at the end (every ending)
    target_disabled: bool = False
    #: what followed the disabling Setpoint (its confirmation), None before the safe stop
    safe_stop: SafeStop | None = None
    #: DUT contract findings: all counted, the first `MAX_KEPT_VIOLATIONS` kept
    violation_count: int = 0
    violations: list[Violation] = field(default_factory=list)
    violations_by_rule: dict[str, int] = field(default_factory=dict)
    #: real time: periods that started later than the overrun threshold
    overruns: int = 0
    #: real time over a link: how long the synchronising period 0 waited for its Command [µs] (None: not synced)
    realtime_sync_us: float | None = None
    #: longest wait for a Command [ns] (wall time)
    max_wait_ns: int = 0
    #: lockstep: waits for a Command the lockstep timeout did not end because the host kept the target's process
    #: stopped or off the CPUs (host stalls), and the time it could not run in them [s]
    host_stalls: int = 0
    host_stall_s: float = 0.0
    #: injected link faults by kind (`--fault`), None without fault injection
    link_faults: dict[str, int] | None = None
    #: the load FMU that ran (`LoadFmuSession.metrics`: model, parameters, doStep calls, warnings), None without
    load_fmu: dict[str, Any] | None = None
    #: a shared CAN bus (src/pmsm_hil/protocol/links/shared_bus.py): other nodes' frames the host received, never taken
    #: as the target's: ids the target never sends, and frames of its ids it cannot have sent (None: not a shared bus)
    bus_foreign_frames: int | None = None
    bus_suspect_frames: int | None = None
    #: the exception behind an internal-error ending (re-raised by the runner after the outputs are written)
    error: BaseException | None = None
    #: metrics-window periods with a restricted-vs-full candidate diagnostic, and those where the
    #: restricted set missed the full-set optimum (in-process targets that report `full_miss`)
    candidate_checked: int = 0
    candidate_misses: int = 0


#: violations kept in the outcome (all are counted)
MAX_KEPT_VIOLATIONS = 100

#: consumer of each block: (period records, raw frames or None when frames are not recorded, the block's
#: metrics-window trace rows — a view valid during the call only)
BlockSink = Callable[[np.ndarray, "np.ndarray | None", np.ndarray], None]
