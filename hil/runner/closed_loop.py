"""The closed loop: plant ↔ target each control period, in lockstep (virtual time) or real time."""

from __future__ import annotations

import contextlib
import gc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S, DynoMechanics
from pmsm_hil.hil.plant_base import PeriodStats, PlantBase
from pmsm_hil.hil.runner.recorder import ByteRecords, FrameTap, frame_records, period_records
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.hil.sensors import SensorModel
from pmsm_hil.protocol.ids import Mode
from pmsm_hil.protocol.messages import Command

_NAN = math.nan


@dataclass(slots=True)
class LoopOutcome:
    """What the loop produced: records, the metrics-window trace, counters and how it ended."""

    periods: ByteRecords
    frames: ByteRecords
    trace: npt.NDArray[np.void]
    window_start_period: int
    completed_periods: int = 0
    wall_time_s: float = 0.0
    deadline_misses: int = 0
    late_commands: int = 0
    lost_commands: int = 0
    lateness_ns: list[int] = field(default_factory=list)
    end_reason: str = "completed"
    safe_state: bool = False
    #: metrics-window periods with a restricted-vs-full candidate diagnostic, and those where the
    #: restricted set missed the full-set optimum (in-process targets that report `full_miss`)
    candidate_checked: int = 0
    candidate_misses: int = 0


BlockSink = Callable[[ByteRecords, ByteRecords, "npt.NDArray[np.void] | None"], None]


class ClosedLoop:
    """One run of the plant against a target through a TargetClient.

    The period is a fixed sequence of steps (`_pace`, `_follow_reference`, `_sample_and_send`,
    `_apply_and_trace`, `_await_command`, `_accept`, `_record`, `_check_end`); what differs between machine
    kinds (frame, record fields, trace layout) is bound once from `cfg.machine` in `__init__`."""

    BLOCK = 1000  # periods per logger block

    def __init__(self, cfg: RunConfig, plant: PlantBase, client: TargetClient, controller_id: int,
                 *, inproc_result: Callable[[], object] | None = None, record_frames: bool = False,
                 sink: BlockSink | None = None) -> None:
        self.cfg = cfg
        self.plant = plant
        self.client = client
        self.controller_id = controller_id
        self.inproc_result = inproc_result
        self.record_frames = record_frames
        self.sink = sink
        self.sensors = SensorModel(cfg.sensors, cfg.motor.pole_pairs)
        layout = cfg.machine.layout
        self._measure = layout.measure
        self._trace_dtype = layout.trace_dtype
        self._trace_columns = layout.trace_columns
        self._second_set_trip = layout.legs > 3

    def run(self) -> LoopOutcome:
        """Run settle + metrics window; stops early on a trip or watchdog (safe state applied).

        The cyclic garbage collector is paused for the loop (a gen-2 pass stalls it for milliseconds);
        the loop allocates no reference cycles, so memory stays bounded."""
        gc_was_enabled = gc.isenabled()
        gc.collect()
        gc.disable()
        try:
            return self._run()
        finally:
            if gc_was_enabled:
                gc.enable()

    # --- set-up -------------------------------------------------------------------------------------
    def _start(self) -> LoopOutcome:
        """Allocate the records and the trace, tap the link, enable the target at the first reference."""
        cfg, sc = self.cfg, self.cfg.scenario
        self._n_total = round(sc.total_s / cfg.ts_s)
        n_settle = round(sc.settle_s / cfg.ts_s)
        self._n_settle = n_settle
        rows_per_period = math.ceil(cfg.ts_s / cfg.trace_dt_s) + 1
        trace = np.zeros((self._n_total - n_settle) * rows_per_period, dtype=self._trace_dtype)
        trace.view(np.uint8)[:] = 0  # touch every page now, not inside the paced loop
        self._trace = trace
        self._trace_view = trace.view(np.float64).reshape(-1, self._trace_columns)
        self._trace_n = 0
        out = LoopOutcome(period_records(), frame_records(), trace, n_settle)
        out.periods.reserve(self._n_total)
        out.frames.reserve(4 * self._n_total)
        self._tap: FrameTap | None = None
        if self.record_frames:
            self._tap = FrameTap(self.client.link, out.frames)
            self.client.link = self._tap
        self._dyno = isinstance(self.plant.mechanics, DynoMechanics)
        self._realtime = cfg.mode == "realtime"
        self._zero_cmd = Command(seq=0, states=(0,), durations_ns=(cfg.ts_ns,))
        self._pending = self._zero_cmd
        self._pending_split: tuple[int, int, int] = (0, 0, 0)
        self._pending_tref = _NAN
        self._silent = 0
        self._speed_ref_rpm = sc.speed_reference_rpm(0.0)
        self._enable(self._speed_ref_rpm)
        self._load_value = sc.load_profile().value_and_slope
        self._speed_reference = sc.speed_reference_rpm
        self._ideal, self._vdc = cfg.sensors.ideal, cfg.motor.vdc
        self._i_trip, self._w_trip = cfg.motor.i_trip, cfg.motor.speed_trip_rpm * RPM_TO_RAD_S
        self._poll_command = self.client.poll_command
        self._timeout_ns = int(cfg.lockstep_timeout_s * 1e9)
        self._t_wall0 = time.perf_counter_ns()
        self._next_start = self._t_wall0
        return out

    def _enable(self, ref_rpm: float) -> None:
        self.client.set_setpoint(enable=True, mode=int(Mode.SPEED), reference=ref_rpm * RPM_TO_RAD_S,
                                 controller_id=self.controller_id)

    # --- the period ---------------------------------------------------------------------------------
    def _run(self) -> LoopOutcome:
        out = self._start()
        ts_s, ts_ns, realtime = self.cfg.ts_s, self.cfg.ts_ns, self._realtime
        pace, follow_reference, sample_and_send = self._pace, self._follow_reference, self._sample_and_send
        apply_and_trace, await_command, accept, record = (self._apply_and_trace, self._await_command,
                                                          self._accept, self._record)
        check_end, sink, block = self._check_end, self.sink, self.BLOCK
        for k in range(self._n_total):
            t = k * ts_s
            if realtime:
                pace(out)
            follow_reference(t)
            smp, extra = sample_and_send(k, t)
            st = apply_and_trace(k)
            pending = self._pending
            cmd = await_command(k & 0xFFFF)
            watchdog = accept(cmd, k, out)
            record(out, t, k, smp, st, pending, extra, cmd is None)
            if watchdog:
                out.completed_periods = k + 1
                silent = self._silent
                out.end_reason = (f"watchdog: target silent for {silent} periods "
                                  f"({silent * ts_s * 1e3:.1f} ms); inverter put in the safe state "
                                  f"(zero vector, all lower switches on)")
                self._safe_state(out)
                break
            self._next_start += ts_ns
            out.completed_periods = k + 1
            if sink is not None and (k + 1) % block == 0:
                sink(out.periods, out.frames, None)
            if check_end(out, k, smp, st, extra):
                break
        out.wall_time_s = (time.perf_counter_ns() - self._t_wall0) / 1e9
        out.late_commands = self.client.stale_commands
        out.trace = self._trace[:self._trace_n]
        return out

    def _pace(self, out: LoopOutcome) -> None:
        """Real time: busy-wait for the period start and record how late it began [ns]."""
        next_start = self._next_start
        now = time.perf_counter_ns()
        while now < next_start:
            now = time.perf_counter_ns()
        out.lateness_ns.append(now - next_start)

    def _follow_reference(self, t: float) -> None:
        """Send a new Setpoint when the scenario's speed reference changes at `t` [s]."""
        ref = self._speed_reference(t)
        if ref != self._speed_ref_rpm:
            self._speed_ref_rpm = ref
            self._enable(ref)
            if self._dyno:
                self.plant.mechanics = DynoMechanics(ref)

    def _sample_and_send(self, k: int, t: float) -> tuple[Any, tuple[float, ...]]:
        """Sample the plant at the period start and send Measurement k (the machine's frame)."""
        smp = self.plant.sample()
        meas, extra = self._measure(k & 0xFFFF, smp, self.sensors, self._ideal, self._vdc)
        tap = self._tap
        if tap is not None:
            tap.t, tap.seq = t, k
        self.client.send_measurement(meas)
        return smp, extra

    def _apply_and_trace(self, k: int) -> PeriodStats:
        """Advance the plant one period with the pending command; keep the trace of the metrics window."""
        pending = self._pending
        if pending.mirror:  # symmetric command: s0..s(n-1), s(n-2)..s0 (same durations)
            st = self.plant.advance(*pending.expanded())
        else:
            st = self.plant.advance(pending.states, pending.durations_ns)
        if k >= self._n_settle:
            tr = self.plant.last_trace
            n_rows = tr.shape[0]
            self._trace_view[self._trace_n:self._trace_n + n_rows] = tr
            self._trace_n += n_rows
        return st

    def _await_command(self, seq: int) -> Command | None:
        """Command `seq`: polled until the deadline (real time), the lockstep timeout (another process)
        or at once (in-process target, which answers inside the poll)."""
        poll_command = self._poll_command
        cmd = poll_command(seq)
        if cmd is None:
            if self._realtime:
                deadline = self._next_start + self.cfg.ts_ns
                while cmd is None and time.perf_counter_ns() < deadline:
                    cmd = poll_command(seq)
            elif self.inproc_result is None:
                deadline = time.perf_counter_ns() + self._timeout_ns
                while cmd is None and time.perf_counter_ns() < deadline:
                    cmd = poll_command(seq)
        return cmd

    def _accept(self, cmd: Command | None, k: int, out: LoopOutcome) -> bool:
        """Make `cmd` (or the miss policy's command) the pending one for the next period; True when the
        watchdog ends the run (target silent for `watchdog_periods`)."""
        cfg = self.cfg
        if cmd is None:
            self._silent += 1
            out.lost_commands += 1
            if self._realtime:
                out.deadline_misses += 1
            next_cmd = self._zero_cmd if cfg.miss_policy == "zero" else self._pending
            self._next_pending = (next_cmd, self._pending_split, self._pending_tref)
            return self._silent >= cfg.watchdog_periods
        self._silent = 0
        res = self.inproc_result() if self.inproc_result is not None else None
        if res is not None:
            split, tref = res.split_ns, res.torque_ref  # type: ignore[attr-defined]
            full_miss = getattr(res, "full_miss", 255)
            if full_miss != 255 and k >= self._n_settle:
                out.candidate_checked += 1
                out.candidate_misses += full_miss
        else:
            split, tref = (0, 0, 0), _NAN
        self._next_pending = (cmd, split, tref)
        return False

    def _record(self, out: LoopOutcome, t: float, k: int, smp: Any, st: PeriodStats, applied: Command,
                extra: tuple[float, ...], missed: bool) -> None:
        """Pack period k's record (the command applied in it, the plant's sample and statistics), then move
        to the next pending command."""
        periods = out.periods
        n_st = len(applied.states)
        states3 = (*applied.states, 0, 0)[:3]
        durs3 = (*applied.durations_ns, 0, 0)[:3]
        load_t = self._load_value(t)[0]
        periods.pack_into(
            periods.buf, periods.end,
            t, k, smp.i_a, smp.i_b, smp.i_c, smp.i_d, smp.i_q, smp.torque, smp.omega_m, smp.theta_e,
            self._pending_tref, self._speed_ref_rpm * RPM_TO_RAD_S, load_t, n_st, *states3, *durs3,
            applied.vector_id, applied.candidates, applied.exec_time_ns, *self._pending_split,
            st.leg_transitions, st.boundary_transitions, st.narrow_pulses, 0, int(missed),
            st.narrow_pulses_gated, applied.mirror, *extra)
        periods.end += periods.size
        self._pending, self._pending_split, self._pending_tref = self._next_pending

    def _check_end(self, out: LoopOutcome, k: int, smp: Any, st: PeriodStats, extra: tuple[float, ...]) -> bool:
        """Target fault or plant trip (instantaneous overcurrent/overspeed): safe state, True to stop."""
        if self.client.faults:
            f = self.client.faults[0]
            out.end_reason = f"target fault code {f.code} (detail {f.detail}); inverter put in the safe state"
            self._safe_state(out)
            return True
        plant, i_trip, w_trip = self.plant, self._i_trip, self._w_trip
        if (abs(smp.i_a) > i_trip or abs(smp.i_b) > i_trip or abs(smp.i_c) > i_trip
                or abs(smp.omega_m) > w_trip or (self._second_set_trip and max(abs(x) for x in extra[:3]) > i_trip)
                or st.peak_current_a > i_trip):
            reason = plant.check_trips(smp) or (
                f"overcurrent: peak |i| = {st.peak_current_a:.2f} A inside the period > i_trip = {i_trip:.2f} A")
            out.end_reason = f"plant trip: {reason}; inverter put in the safe state (zero vector)"
            self._safe_state(out)
            return True
        trip = plant.check_trips() if k == self._n_total - 1 else None
        if trip is not None:
            out.end_reason = f"plant trip: {trip}; inverter put in the safe state (zero vector)"
            self._safe_state(out)
            return True
        return False

    def _safe_state(self, out: LoopOutcome) -> None:
        """Zero vector (all lower switches on) and the target disabled."""
        out.safe_state = True
        self.plant.advance((0,), (self.cfg.ts_ns,))
        with contextlib.suppress(Exception):
            self.client.set_setpoint(enable=False, mode=int(Mode.SPEED), reference=0.0,
                                     controller_id=self.controller_id)
