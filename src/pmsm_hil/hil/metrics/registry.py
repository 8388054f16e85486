"""The metrics registry: every metrics.json key once, with its label, unit, table format, definition and the
views that show it. The CLI summary, `hil compare` rows/CSV/figures, the HTML report and docs/metrics.md read
it; adding a metric is one `Metric(...)` line here plus its computation (docs/recipes.md, "A new metric").

Run `python -m pmsm_hil.hil.metrics.registry --check` (CI) to check docs/metrics.md's key table against the
registry, `--write` to regenerate it.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

#: Views: the `hil run` summary, the HTML report's table and bar charts, a `hil compare` row (copied from the
#: run or computed by compare; numeric rows are aggregated over the initial rotor angles), compare's bar figure.
CLI: Final = "cli"
REPORT: Final = "report"
REPORT_BARS: Final = "report_bars"
COMPARE_ROW: Final = "compare_row"
COMPARE_BARS: Final = "compare_bars"
#: Sources: the window metrics (`compute_run_metrics`), the runner's run-level facts, or `hil compare`.
WINDOW: Final = "window"
RUN: Final = "run"
COMPARE: Final = "compare"


@dataclass(frozen=True, slots=True)
class Metric:
    """One metrics key. `sub`: a field of a dict-valued key (e.g. exec_time_us → median); `fmt`: format spec
    of a table cell ("" = str); `unit`: SI or the stated unit ("" for counts and text)."""

    key: str
    label: str
    unit: str
    doc: str
    fmt: str = ".4g"
    sub: str | None = None
    source: str = WINDOW
    views: frozenset[str] = frozenset()

    @property
    def name(self) -> str:
        """`key` or `key.sub`."""
        return self.key if self.sub is None else f"{self.key}.{self.sub}"

    @property
    def title(self) -> str:
        """Label with the unit in brackets."""
        return f"{self.label} [{self.unit}]" if self.unit else self.label

    def value(self, metrics: Mapping[str, Any]) -> Any:
        """The value in a metrics dict (None if absent)."""
        value = metrics.get(self.key)
        if self.sub is not None:
            value = value.get(self.sub) if isinstance(value, Mapping) else None
        return value

    def format(self, value: Any) -> str:
        """Table cell text: "n/a" for None or non-finite, else `fmt` (str for text)."""
        if value is None or (isinstance(value, float) and not math.isfinite(value)):
            return "n/a"
        if self.fmt and isinstance(value, int | float) and not isinstance(value, bool):
            return format(value, self.fmt)
        return str(value)


def _m(key: str, label: str, unit: str, doc: str, fmt: str = ".4g", *views: str, sub: str | None = None,
       source: str = WINDOW) -> Metric:
    return Metric(key, label, unit, doc, fmt, sub, source, frozenset(views))


METRICS: Final[tuple[Metric, ...]] = (
    # run-level facts (the runner)
    _m("controller", "controller", "", "controller name (`--controller`)", "", CLI, REPORT, source=RUN),
    _m("scenario", "scenario", "", "scenario name", "", CLI, REPORT, source=RUN),
    _m("speed_ref_rpm", "speed ref", "rpm", "scenario speed reference", ".0f", REPORT, source=RUN),
    _m("load_nm", "load", "N·m", "scenario load torque (null with a load FMU)", ".2f", REPORT, source=RUN),
    _m("load_fmu", "load FMU", "", "the load FMU that ran (`--load-fmu`): `{path, fmi_version, model_name, guid | "
       "instantiation_token, model_identifier, speed, torque, parameters, steps, warnings}` (steps: doStep calls "
       "that succeeded, warnings: calls that returned a warning); null without one", "", source=RUN),
    _m("mode", "mode", "", "lockstep or realtime", "", source=RUN),
    _m("link_spec", "link", "", "link SPEC of the run", "", source=RUN),
    _m("loop", "loop", "", "the period loop that ran: `native` (C, src/pmsm_hil/hil/runner/c/loop.c) or `python`",
       "", source=RUN),
    _m("loop_note", "loop note", "", "why the Python loop ran (`--loop python`: the test suite's reference loop "
       "only); null for the native loop", "", source=RUN),
    _m("end_reason", "end", "", "`completed`, or why the run stopped (trip, watchdog, target fault)", "", CLI,
       REPORT, source=RUN),
    _m("end_code", "end code", "", "how the run ended = exit code of `hil run`: 0 completed, 1 internal error, "
       "3 safety stop (watchdog, trip, target fault, safe stop not confirmed), 4 DUT contract violation, "
       "5 setpoint not held (a completed run with `--expect-hold` and `setpoint_held` false), 130 interrupted", "d",
       CLI,
       source=RUN),
    _m("end_period", "end period", "", "index of the last period run and logged (−1: none); the MCAP holds "
       "end_period + 1 periods", "d", source=RUN),
    _m("safe_state", "safe state", "", "true when the run ended in the safe state", "", source=RUN),
    _m("target_disabled", "target disabled", "", "true when the disabling Setpoint was sent at the end", "",
       source=RUN),
    _m("target_link", "target link", "", "the target end's own link counters (LinkStats names; a spawned target's "
       "as it printed them when stopped, with `socket_drops` over UDP and, native, its waits; an in-process "
       "target's end of the link); null when the host cannot know them (external targets, the native loop's "
       "in-process core)", "", source=RUN),
    _m("link_losses", "link losses", "", "frames lost on the link `{to_target, to_host}`: gaps in the sender's link "
       "sequence numbers plus socket buffer drops, as counted by the receiving end (null: not known); a run that "
       "ends on a missing Command or the watchdog while they are non-zero says so in `end_reason`", "",
       source=RUN),
    _m("link_authenticated", "link authenticated", "", "true when the run's frames carried a MAC and a freshness "
       "value (UDP and serial links: on by default for spawned targets, `key=`/`keyfile=` for external ones; "
       "docs/protocol.md, 'Authenticated frames')", "", source=RUN),
    _m("link_auth_dropped", "link auth dropped", "", "frames dropped for their authentication `{to_target, "
       "to_host}` (a MAC that failed or was missing, a replayed freshness value: `auth_failed` + `auth_replayed` "
       "of the receiving end's link counters; null: not known): spoofed, altered or replayed frames", "",
       source=RUN),
    _m("bus_foreign_frames", "bus foreign frames", "", "a shared CAN bus (socketcan, python-can adapters, a link "
       "with `shared=true`): frames of ids the target never sends (another node's), counted, never taken as the "
       "target's (docs/protocol.md, 'A shared bus'); null: not a shared bus", "d", source=RUN),
    _m("bus_suspect_frames", "bus suspect frames", "", "a shared CAN bus: frames of the target's ids it cannot "
       "have sent (a Command for no open seq or a second reply, an implausible FaultTarget or ConfigAck), counted "
       "as another node's, not findings; null: not a shared bus", "d", source=RUN),
    _m("safe_stop_confirmed", "safe stop confirmed", "", "true when the target answered the disabling Setpoint "
       "with a HeartbeatTarget in state idle within 500 ms (docs/runner.md, 'Safe stop on every exit path'); "
       "false: it did not (a completed run then ends with exit 3); null when the Setpoint could not be sent", "",
       CLI, source=RUN),
    _m("safe_stop_wait_ms", "safe stop wait", "ms", "wall time from the disabling Setpoint to its confirmation "
       "(or the whole wait when unconfirmed)", ".3f", source=RUN),
    _m("safe_stop_observed", "safe stop observed", "", "what followed the disabling Setpoint, one line: the "
       "confirmation, or the HeartbeatTarget states and other frames received instead", "", source=RUN),
    _m("dut_violations", "DUT violations", "", "DUT contract findings (docs/runner.md, 'DUT contract'), all "
       "counted; the run ends at the first beyond `tolerate`", "d", CLI, source=RUN),
    _m("dut_violations_by_rule", "DUT violations by rule", "", "findings per rule: `{missing, sequence, "
       "state_code, durations, frame, duty}`", "", source=RUN),
    _m("dut_violation_list", "DUT violation list", "", "the first 100 findings: `{period, seq, rule, frame, "
       "detail}`", "", source=RUN),
    _m("tolerate", "tolerated violations", "", "`--tolerate N`: findings accepted before the run ends", "d",
       source=RUN),
    _m("link_faults", "link faults", "", "`--fault`: injected faults `{dropped, duplicated, corrupted, delayed, "
       "reordered}` (null without fault injection)", "", source=RUN),
    _m("command_wait_max_us", "command wait max", "µs", "longest wall-time wait for a Command (targets in "
       "another process or on a board)", ".1f", source=RUN),
    _m("host_stalls", "host stalls", "", "waits for a Command (lockstep) or for the safe stop's confirmation that "
       "their timeout did not end because the host kept the target's process stopped or off the CPUs (the wait went "
       "on: not the firmware's fault; targets in a process the host can observe: sil, qemu, spawn)", "d",
       source=RUN),
    _m("host_stall_s", "host stall time", "s", "the time the target's process could not run in those waits (from "
       "20 ms into each wait on)", ".3f", source=RUN),
    _m("overruns", "overruns", "", "real time: periods that started later than `overrun_threshold_us`", "d", CLI,
       source=RUN),
    _m("realtime_sync_us", "real-time sync", "µs", "real time over a link: period 0 is the synchronising exchange, "
       "its Command awaited as in lockstep (a cold target's first answer); the wall clock of the periods starts "
       "when it arrives; how long it took (null: in process, or no Command came)", ".1f", source=RUN),
    _m("cpu_dma_latency_us", "CPU wake-up latency held", "µs", "real time: the CPUs' wake-up latency the run held "
       "through PM QoS (`--cpu-dma-latency`, /dev/cpu_dma_latency; null: not held, the warnings say why)", "d",
       source=RUN),
    _m("overrun_threshold_us", "overrun threshold", "µs", "real time: `--overrun-threshold` (default Ts/2)", ".1f",
       source=RUN),
    _m("warnings", "warnings", "", "lines the summary warns with (overruns, tolerated violations)", "",
       source=RUN),
    _m("total_periods", "total periods", "", "periods run, settling included", "d", source=RUN),
    _m("total_wall_time_s", "total wall time", "s", "wall time of the whole loop", source=RUN),
    _m("loop_rate_total_hz", "loop rate (total)", "periods/s", "total_periods / total_wall_time_s", ".0f",
       source=RUN),
    _m("lateness_us", "lateness", "µs", "real time: `{median, p99, max}` of how late each period started "
       "(quantiles within 0.39 %, max exact, in fixed memory: below)",
       source=RUN),
    _m("lateness_histogram_us", "lateness histogram", "µs", "real time: `{edges_us, counts}`, period starts per "
       "lateness bin [edges_us[i], edges_us[i+1]) µs, the last bin open-ended", "", source=RUN),
    _m("speed_error_pct", "speed error", "%", "100 · (speed_mean_rpm − reference) / reference", ".3g", source=RUN),
    _m("speed_reference_missed", "speed reference missed", "", "completed runs: true when the speed over the last "
       "10 % of the window is off the reference by more than 10 % (≥ 5 rpm; src/pmsm_hil/hil/runner/run_limits.py); "
       "null otherwise", "", source=RUN),
    _m("setpoint_mode", "setpoint mode", "", "what the setpoint verdict judges: `speed` (`hil run` drives Setpoint "
       "mode 0)", "", source=RUN),
    _m("setpoint_held", "setpoint held", "", "completed runs: true when the mean speed over the hold span (the last "
       "10 % of the metrics window) is within `hold_tolerance_pct` of the mean reference (at least 5 rpm); null "
       "otherwise, the reason in `not_applicable` (src/pmsm_hil/hil/runner/setpoint_hold.py)", "", CLI, REPORT,
       source=RUN),
    _m("setpoint_error", "setpoint error", "", "`{absolute, relative_pct, unit, reference, measured}`: measured − "
       "reference over the hold span (rpm, % of the reference); null without a verdict", "", source=RUN),
    _m("hold_tolerance_pct", "hold tolerance", "%", "tolerance of `setpoint_held` (`--hold-tolerance`, the "
       "scenario's `hold_tolerance_pct`, default 2)", ".3g", source=RUN),
    _m("not_applicable", "not applicable", "", "`{key: reason}` of the metrics that are not defined for this run or "
       "window (null in metrics.json, never a number): the harmonic metrics when the stator frequency changes or is "
       "~ 0, the setpoint verdict of a run that did not complete", "", source=RUN),
    _m("exec_time_first_us", "exec time cold start", "µs", "`{periods, first, max}`: execution times of the run's "
       "first 10 periods (cold start: first calls, page faults, caches), left out of `exec_time_us`", "",
       source=RUN),
    # the metrics window
    _m("periods", "periods (window)", "", "N periods in the window", "d", CLI),
    _m("sim_time_s", "simulated time", "s", "N·Ts"),
    _m("wall_time_s", "wall time", "s", "wall time of the window"),
    _m("loop_rate_hz", "loop rate", "periods/s", "N / wall time (null if wall time is 0)", ".0f", CLI, REPORT),
    _m("torque_mean_nm", "torque mean", "N·m", "time-weighted mean of the trace torque, T_av", ".3f", CLI, REPORT,
       COMPARE_ROW),
    _m("torque_ripple_rms_nm", "torque ripple RMS", "N·m", "eq. (20) below", ".3f", CLI, REPORT, REPORT_BARS,
       COMPARE_ROW, COMPARE_BARS),
    _m("torque_ripple_pp_nm", "torque ripple p-p", "N·m", "max − min of the trace torque", ".3f", CLI, REPORT,
       COMPARE_ROW),
    _m("torque_error_mean_nm", "torque error mean", "N·m", "T_av − T_hold: T_hold = mean of the torque the drive "
       "must deliver to follow the host's speed reference, T_load + B·ω_ref + J·dω_ref/dt (inertia mechanics; "
       "J term 0 on the dyno), from the records the host writes for every target (below)", "+.3f", CLI,
       COMPARE_ROW),
    _m("torque_error_reference", "torque error reference", "", "what `torque_error_mean_nm` is against: "
       "`hold: load + B·ω_ref + J·dω_ref/dt`", ""),
    _m("load_torque_mean_nm", "load torque mean", "N·m", "mean of the periods' `load_torque` (the scenario's "
       "profile, or a load FMU's output held over each period)", ".3f", CLI),
    _m("speed_mean_rpm", "speed mean", "rpm", "time-weighted mean of trace `omega_m` · 60/2π", ".1f", CLI, REPORT,
       COMPARE_ROW),
    _m("current_thd_pct", "current THD (h2..40)", "%", "integer harmonics 2..40 of phase a (below)", ".2f", CLI,
       REPORT, REPORT_BARS, COMPARE_ROW, COMPARE_BARS),
    _m("current_thd_total_pct", "current THD (all)", "%", "all non-fundamental content of phase a (below)", ".2f",
       CLI, REPORT, COMPARE_ROW),
    _m("current_fundamental_a", "current fundamental", "A", "fundamental amplitude of phase a", ".4g", CLI),
    _m("current_fundamental_hz", "fundamental frequency", "Hz", "f1: the stator electrical frequency measured from "
       "the phase currents over the THD span (below; slip included for an induction machine); null when ~ 0 or "
       "changing (not applicable)",
       ".4g", CLI),
    _m("current_rotor_electrical_hz", "rotor electrical frequency", "Hz", "p·|ω̄_m|/2π over the THD span (= f1 for "
       "a synchronous machine; f1 − slip frequency for an induction machine)"),
    _m("current_fundamental_change_pct", "fundamental change", "%", "spread of f1 over the THD span's 4 quarters, "
       "% of f1; above 2 % the harmonic metrics are not applicable"),
    _m("current_thd_phases_pct", "THD per phase", "%", "both THD figures per phase a/b/c"),
    _m("current_thd_note", "THD note", "", "reason when THD is null (also in `not_applicable`)", ""),
    _m("current_distortion_rms_a", "distortion RMS", "A", "fundamental RMS · THD_total: all non-fundamental "
       "content of phase a", ".1f", COMPARE_ROW),
    _m("xy_current_rms_a", "x-y current RMS", "A", "dual three-phase: RMS of the harmonic-subspace current "
       "sqrt(i_x² + i_y²) (absent for three-phase runs)", ".1f", COMPARE_ROW),
    _m("switching_freq_khz", "switching freq f_av", "kHz", "f_av (below), all transitions", ".2f", CLI, REPORT,
       REPORT_BARS, COMPARE_ROW, COMPARE_BARS),
    _m("switching_freq_intra_khz", "f_av intra-period", "kHz", "f_av without period-boundary transitions", ".2f",
       CLI, COMPARE_ROW),
    _m("candidate_miss_rate", "miss rate", "", "fraction of window periods where a restricted-candidate "
       "controller (fcs-mpc-1/2, dbcc-mpc) missed the full 19-vector optimum (in-process targets; null otherwise)",
       ".3f", COMPARE_ROW, COMPARE_BARS, source=RUN),
    _m("exec_time_us", "exec time", "µs", "`{median, p99, max}` of `exec_time_ns` over the window, the run's first "
       "10 periods (cold start, `exec_time_first_us`) left out"),
    _m("exec_time_us", "exec median", "µs", "median controller execution time", ".3f", REPORT, REPORT_BARS,
       sub="median"),
    _m("exec_time_us", "exec p99", "µs", "99th percentile of the controller execution time", ".3f", REPORT,
       sub="p99"),
    _m("exec_split_us", "exec split", "µs", "`{measure, reference, predict}` medians of `exec_split_ns`"),
    _m("exec_instructions", "exec instructions", "", "qemu targets: `{median, p99, max, steps}` of the exact "
       "instructions per control step (QEMU plugin, between the firmware's step markers) over the metrics window; "
       "`exec_time_us` is then the estimate instructions × CPI / `mcu_clock_hz` (docs/firmware_api.md)",
       source=RUN),
    _m("exec_instructions", "exec instructions", "", "median instructions per control step (qemu targets)", ".0f",
       REPORT, sub="median", source=RUN),
    _m("mcu_clock_hz", "MCU clock", "Hz", "qemu targets: the clock of the `exec_time_us` estimate (`--mcu-clock`)",
       ".4g", source=RUN),
    _m("exec_time_model", "exec time model", "", "qemu targets: how `exec_time_us` is estimated (cycle model)", "",
       source=RUN),
    _m("board", "board", "", "stm32g4 targets: the board description (`--board`)", "", REPORT, source=RUN),
    _m("board_carrier_hz", "board carrier", "Hz", "stm32g4 targets: the PWM carrier of the firmware's TIM1 set-up",
       ".5g", REPORT, source=RUN),
    _m("board_dead_time_ns", "board dead time", "ns", "stm32g4 targets: the dead time of TIM1's BDTR (applied to "
       "the duties by each phase current's sign)", ".4g", REPORT, source=RUN),
    _m("board_isr_time_us", "ISR time", "µs", "stm32g4 targets: `{median, p99, max}` of the cycles spent in "
       "interrupt handlers per control period over the metrics window / the core clock (CPI 1, a lower bound)",
       source=RUN),
    _m("board_isr_time_us", "ISR time", "µs", "median interrupt-handler time per period (stm32g4 targets)", ".3g",
       CLI, REPORT, sub="median", source=RUN),
    _m("board_cpu_load", "CPU load", "", "stm32g4 targets: share of the core's cycles not asleep in WFI/WFE over "
       "the metrics window", ".3f", CLI, REPORT, source=RUN),
    _m("board_late_compares", "late compares", "", "stm32g4 targets: control periods whose TIM1 compare values "
       "were written after the update event that followed their ADC trigger (they apply one period late)", ".0f",
       CLI, REPORT, source=RUN),
    _m("board_first_late_period", "first late period", "", "stm32g4 targets: the control period of the first "
       "late compare values (null: none)", ".0f", REPORT, source=RUN),
    _m("board_handlers", "handlers", "", "stm32g4 targets: per exception (SysTick, IRQn) `{entries, time_us, "
       "latency_us}`: entries, `{median, p99, max}` of each handler's time and of the latency from its line's "
       "assertion (trigger, flag) to its first instruction, over the whole run", "", source=RUN),
    _m("board_adc_sample_us", "ADC sample instant", "µs", "stm32g4 targets: `{median, p99, max}` of the ADC "
       "sampling instants after the period start (the carrier valley), last samples of the run", source=RUN),
    _m("board_setpoints_dropped", "setpoints dropped", "", "stm32g4 targets without an FDCAN1 model: enabling "
       "Setpoints the firmware could not receive", ".0f", source=RUN),
    _m("board_break_trips", "TIM1 breaks", "", "stm32g4 targets: times TIM1's break input went active with the "
       "firmware's BDTR.BKE set (the board's overcurrent protection, [break_input]) or the board cut the outputs "
       "for a disabling Setpoint (MOE cleared, the outputs at their idle state)", ".0f", source=RUN),
    _m("board_configs_acked", "configs acked by board", "", "stm32g4 targets without an FDCAN1 model: "
       "ConfigParams the board acknowledged on the firmware's behalf", ".0f", source=RUN),
    _m("board_idle_periods", "idle periods", "", "stm32g4 targets with an FDCAN1 model: firmware periods run outside "
       "the control periods for frames that arrived between them (configuration, the safe stop)", ".0f",
       source=RUN),
    _m("board_link", "board link", "", "stm32g4 targets built on the firmware API (`hil fw build --board stm32g474 "
       "--src DIR`): `fdcan1`, the frames carried by the board's emulated FDCAN1", "", REPORT, source=RUN),
    _m("board_can_bitrates", "CAN bit rates", "bit/s", "stm32g4 targets on FDCAN1: `[nominal, data]` bit rates the "
       "firmware configured", "", source=RUN),
    _m("board_turnaround_us", "MCU turnaround", "µs", "stm32g4 targets on FDCAN1: `{median, p99, max}` from a "
       "Measurement's arrival on FDCAN1 to the start of its Command on the bus (interrupt, target core, step, "
       "frame encoding; CPI 1, a lower bound) over the metrics window", source=RUN),
    _m("board_turnaround_us", "MCU turnaround", "µs", "median MCU turnaround per period (stm32g4 targets on "
       "FDCAN1)", ".3g", CLI, REPORT, sub="median", source=RUN),
    _m("board_turnaround_cycles", "MCU turnaround", "cycles", "stm32g4 targets on FDCAN1: the turnaround in core "
       "cycles (= instructions at CPI 1, exception entries 12 and returns 10 cycles), `{median, p99, max}`",
       source=RUN),
    _m("board_late_replies", "late replies", "", "stm32g4 targets on FDCAN1: Commands that left the bus after the "
       "next Measurement's slot (late on a real-time bench at --ts)", ".0f", CLI, REPORT, source=RUN),
    _m("board_missing_replies", "missing replies", "", "stm32g4 targets on FDCAN1: Measurements the firmware did "
       "not answer within 20 periods", ".0f", source=RUN),
    _m("candidates_evaluated_mean", "candidates / step", "", "mean of `candidates`", ".0f", CLI, COMPARE_ROW),
    _m("narrow_pulses", "narrow pulses", "", "Σ leg pulses shorter than T_lim = 2·T_dead + T_mpw requested by the "
       "controller", ".0f", CLI, COMPARE_ROW),
    _m("narrow_pulses_gated", "narrow pulses gated", "", "Σ narrow pulses that reached the gate (not suppressed "
       "by T_mpw); 0 for records that predate the field", ".0f", COMPARE_ROW),
    _m("deadline_misses", "deadline misses", "", "real time: commands that missed their period", "d", CLI),
    _m("late_periods", "late periods", "", "count of `late` flags"),
    _m("missed_periods", "missed periods", "", "count of `missed` flags"),
    _m("link", "link", "", "`{frames_tx, frames_rx, crc_errors, lost, late}` plus the link's own counters "
       "(the native loop over a link: also `blocked`, `spin_backoffs`, `spin_early_ends`; UDP: `socket_drops`, "
       "datagrams the kernel dropped for the host's socket, its receive buffer full; SocketCAN: `kernel_dropped`; "
       "`config_resent`, ConfigParam frames sent again for want of a ConfigAck within 0.25 s of wall time, and "
       "`config_acks_repeated`, the target's ConfigAcks to them: a target slow to start)"),
    _m("link", "kernel dropped", "", "SocketCAN: frames the host's kernel dropped for the link's socket, its "
       "receive buffer full (`SO_RXQ_OVFL`, read on every receive; the buffer holds `rx_frames` frames, "
       "docs/protocol.md); absent on other links", "d", sub="kernel_dropped"),
    # computed by `hil compare` per row
    _m("exec_time_us_median", "exec median", "µs", "`exec_time_us.median` of the run", ".3f", COMPARE_ROW,
       source=COMPARE),
    _m("t_reach_98pct_s", "t98", "s", "accel: first time the speed reaches 98 % of the reference", ".3f",
       COMPARE_ROW, source=COMPARE),
    _m("eval_e", "E", "", "the preset's evaluation index (ripple and f_av weighted as the paper)", ".3f",
       COMPARE_ROW, source=COMPARE),
    _m("eval_e_intra", "E intra", "", "`eval_e` with f_av intra-period", ".3f", COMPARE_ROW, source=COMPARE),
    _m("equal_fav_target_khz", "equal f_av target", "kHz", "equal-f_av runs: the f_av they were matched to", ".2f",
       COMPARE_ROW, source=COMPARE),
)


def in_view(view: str) -> tuple[Metric, ...]:
    """The metrics shown by `view`, in registry order."""
    return tuple(m for m in METRICS if view in m.views)


def row_keys(*, source: Iterable[str] = (WINDOW, RUN, COMPARE)) -> tuple[str, ...]:
    """Keys of the numeric `hil compare` row metrics from these sources (no sub-keys)."""
    wanted = set(source)
    return tuple(m.key for m in in_view(COMPARE_ROW) if m.sub is None and m.source in wanted)


def by_name(name: str) -> Metric:
    """The metric `key` or `key.sub`; KeyError naming it when unknown."""
    for m in METRICS:
        if m.name == name:
            return m
    raise KeyError(f"metric {name!r} is not in the registry (src/pmsm_hil/hil/metrics/registry.py)")


# --- docs/metrics.md key table --------------------------------------------------------------------------
DOC_PATH = Path(__file__).resolve().parents[4] / "docs" / "metrics.md"
_START = "<!-- metrics-registry:start (generated by python -m pmsm_hil.hil.metrics.registry --write) -->"
_END = "<!-- metrics-registry:end -->"


def doc_table() -> str:
    """The generated Markdown table of every key (sub-keys folded into their key's row)."""
    lines = [_START, "| key | definition | unit | source |", "|---|---|---|---|"]
    for m in METRICS:
        if m.sub is None:
            lines.append(f"| `{m.key}` | {m.doc} | {m.unit or '–'} | {m.source} |")
    lines.append(_END)
    return "\n".join(lines)


def _doc_with_table(text: str) -> str:
    if _START not in text or _END not in text:
        raise ValueError(f"{DOC_PATH}: markers {_START!r} … {_END!r} not found")
    head, rest = text.split(_START, 1)
    _, tail = rest.split(_END, 1)
    return head + doc_table() + tail


def main(argv: list[str] | None = None) -> int:
    """`--check`: exit 1 if docs/metrics.md's key table differs from the registry; `--write`: rewrite it."""
    ap = argparse.ArgumentParser(prog="python -m pmsm_hil.hil.metrics.registry")
    group = ap.add_mutually_exclusive_group(required=True)
    group.add_argument("--check", action="store_true")
    group.add_argument("--write", action="store_true")
    args = ap.parse_args(argv)
    text = DOC_PATH.read_text(encoding="utf-8")
    want = _doc_with_table(text)
    if args.write:
        DOC_PATH.write_text(want, encoding="utf-8")
        return 0
    if want != text:
        print(f"{DOC_PATH}: key table differs from src/pmsm_hil/hil/metrics/registry.py (run with --write)",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
