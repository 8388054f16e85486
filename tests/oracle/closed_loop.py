"""The Python period loop: plant ↔ target each control period, in lockstep (virtual time) or real time.

Not part of the product: the C loop (src/pmsm_hil/hil/runner/c/loop.c) runs every run. This is the test suite's
reference (the oracle the C loop is proven against, record for record, frame for frame): `run_reference_loop` is
registered with the runner by tests/conftest.py (`--loop python`)."""

from __future__ import annotations

import contextlib
import gc
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S, DynoMechanics
from pmsm_hil.hil.plant_base import PeriodStats, PlantBase
from pmsm_hil.hil.pwm import applied_sequence, carrier_half, duties_record
from pmsm_hil.hil.runner import recorder
from pmsm_hil.hil.runner.block_sink import RunSink
from pmsm_hil.hil.runner.contract import MISSING, EndCode, Violation, check_command, describe
from pmsm_hil.hil.runner.fault_setup import install_faults
from pmsm_hil.hil.runner.lockstep_wait import LockstepWait, WaitEnd, host_stall_error
from pmsm_hil.hil.runner.loop_outcome import MAX_KEPT_VIOLATIONS, BlockSink, LoopOutcome
from pmsm_hil.hil.runner.plant_setup import build_plant
from pmsm_hil.hil.runner.recorder import FrameTap, frame_records, period_records
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.safe_stop import SAFE_STOP_TIMEOUT_S, disable_and_confirm, settle_ending
from pmsm_hil.hil.runner.stop_request import StopRequest, deferred_interrupts
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.hil.runner.target_setup import TargetConnection
from pmsm_hil.hil.runner.target_time import TargetTime
from pmsm_hil.hil.sensors import SensorModel
from pmsm_hil.protocol.codec_duty import duty_raw, duty_value
from pmsm_hil.protocol.ids import Mode
from pmsm_hil.protocol.links.faults import FaultyLink
from pmsm_hil.protocol.messages import Command

_NAN = math.nan


def _flat_duties(cmd: Command) -> tuple[float, ...]:
    n, duties = duties_record(cmd)
    return (n, *duties)


class ClosedLoop:
    """One run of the plant against a target through a TargetClient.

    The period is a fixed sequence of steps (`_pace`, `_follow_reference`, `_sample_and_send`,
    `_apply_and_trace`, `_await_command`, `_accept`, `_record`, `_check_end`); what differs between machine
    kinds (frame, record fields, trace layout) is bound once from `cfg.machine` in `__init__`."""

    BLOCK = 1000  # periods per block handed to the sink (logger, metrics, live view)

    def __init__(self, cfg: RunConfig, plant: PlantBase, client: TargetClient, controller_id: int,
                 *, inproc_result: Callable[[], object] | None = None, record_frames: bool = False,
                 sink: BlockSink | None = None, first_duties: tuple[float, ...] = (),
                 own_time: Callable[[float], TargetTime | None] = lambda timeout_s: None) -> None:
        self.cfg = cfg
        #: the target's own time for a wait of a given timeout [s] (TargetConnection.own_time: a target process
        #: the host observes), None: wall time
        self.own_time = own_time
        #: period 0's duties before the target's first reply (a board's outputs at the start; empty: the zero vector)
        self.first_duties = first_duties
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
        self._trace: npt.NDArray[np.void] = np.zeros(0, dtype=self._trace_dtype)  # one block (`_start`)
        self._trace_n = 0  # rows of `_trace` in use
        #: run time [s] the link fault injection sees: the period start in lockstep (time moves in whole
        #: periods), the wall time since the start in real time
        self.clock_s = 0.0
        #: the fault-injecting link (set by the runner before `run`), None without `--fault`
        self.faulty: FaultyLink | None = None

    def run_time_s(self) -> float:
        """Run time [s] for the link fault injection."""
        if self._realtime:
            return (time.perf_counter_ns() - self._t_wall0) / 1e9
        return self.clock_s

    def run(self) -> LoopOutcome:
        """Run settle + metrics window; stops early on a trip or watchdog (safe state applied).

        The cyclic garbage collector is paused for the loop (a gen-2 pass stalls it for milliseconds);
        the loop allocates no reference cycles, so memory stays bounded. Every `BLOCK` periods, and once
        more at the end (the safe stop's frames included), the records go to the sink. Ctrl-C and SIGTERM are
        deferred (`deferred_interrupts`): the loop ends at the next period start, every record counted logged."""
        with deferred_interrupts() as stop:
            return self._run_deferred(stop)

    def _run_deferred(self, stop: StopRequest) -> LoopOutcome:
        gc_was_enabled = gc.isenabled()
        gc.collect()
        gc.disable()
        out = self._start()
        self._stop_asked = lambda: bool(stop.flag)
        try:
            if self._run(out, stop.flag):
                self._end(out, EndCode.INTERRUPTED, "interrupted (Ctrl-C or SIGTERM)")
        except KeyboardInterrupt:  # a handler of the caller's own (signals are deferred only where they raise)
            self._end(out, EndCode.INTERRUPTED, "interrupted (Ctrl-C or SIGTERM)")
        except Exception as exc:  # a bug or a plant fault: still a safe stop and complete outputs
            out.error = exc
            self._end(out, EndCode.INTERNAL_ERROR, f"internal error: {type(exc).__name__}: {exc}")
        finally:
            out.paced_time_s = (time.perf_counter_ns() - self._t_wall0) / 1e9
            out.host_stalls, out.host_stall_s = self._lockstep.host_stalls, self._lockstep.host_stall_s
            self._stop(out)
            out.wall_time_s = (time.perf_counter_ns() - self._t_wall0) / 1e9
            out.late_commands = self.client.stale_commands
            try:
                self._flush(out)
            finally:
                if gc_was_enabled:
                    gc.enable()
        return out

    def _flush(self, out: LoopOutcome) -> None:
        """Hand the block (periods, frames, trace rows since the last flush) to the sink and start a new one."""
        periods = out.periods.take()
        frames = out.frames.take() if self.record_frames else None
        trace = self._trace[:self._trace_n]
        if out.lateness_ns:
            out.lateness_us.add(np.asarray(out.lateness_ns, dtype=np.int64))
            out.lateness_ns.clear()
        try:
            if self.sink is not None:
                self.sink(periods, frames, trace)
        finally:
            self._trace_n = 0

    # --- set-up -------------------------------------------------------------------------------------
    def _start(self) -> LoopOutcome:
        """Allocate one block of records and trace, tap the link, enable the target at the first reference."""
        cfg, sc = self.cfg, self.cfg.scenario
        self._n_total = round(sc.total_s / cfg.ts_s)
        n_settle = round(sc.settle_s / cfg.ts_s)
        self._n_settle = n_settle
        rows_per_period = math.ceil(cfg.ts_s / cfg.trace_dt_s) + 1
        trace = np.zeros(self.BLOCK * rows_per_period, dtype=self._trace_dtype)
        trace.view(np.uint8)[:] = 0  # touch every page now, not inside the paced loop
        self._trace = trace
        self._trace_view = trace.view(np.float64).reshape(-1, self._trace_columns)
        self._trace_n = 0
        keep = self._n_total <= recorder.KEEP_PERIODS_MAX  # read now (tests lower it)
        out = LoopOutcome(period_records(keep=keep), frame_records(keep=False), trace[:0], n_settle)
        out.periods.reserve(self._n_total if keep else self.BLOCK)
        out.frames.reserve(4 * self.BLOCK)
        self._tap: FrameTap | None = None
        if self.record_frames:
            self._tap = FrameTap(self.client.link, out.frames)
            self.client.link = self._tap
        self._dyno = isinstance(self.plant.mechanics, DynoMechanics)
        self._realtime = cfg.mode == "realtime"
        self._zero_cmd = Command(seq=0, states=(0,), durations_ns=(cfg.ts_ns,))
        self._pending = (Command(seq=0, states=(), durations_ns=(), duties=self.first_duties) if self.first_duties
                         else self._zero_cmd)
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
        self._take_anomalies = self.client.take_anomalies
        self._max_state = self.cfg.machine.layout.max_state_code
        self._ts_ns = cfg.ts_ns
        self._pwm_update = cfg.pwm_update
        if cfg.adc_delay_ns:
            raise ParameterError("--adc-delay: the reference loop samples at the period start only (the C loop "
                                 "serves it)")
        self._overrun_ns = cfg.overrun_threshold_ns
        other_process = not self._realtime and self.inproc_result is None
        #: the lockstep wait for a Command (the C loop's rule: the target's own time when its process is observed)
        self._lockstep = LockstepWait(self.own_time(cfg.lockstep_timeout_s) if other_process else None,
                                      cfg.lockstep_timeout_s, cfg.host_stall_limit_s)
        self._stop_asked: Callable[[], bool] = lambda: False
        #: how the wait for the period's Command ended the run (a host stall, a stop request), None: it did not
        self._wait_end: WaitEnd | None = None
        self._wait_ns = 0
        self._t_wall0 = time.perf_counter_ns()
        self._next_start = self._t_wall0
        return out

    def _enable(self, ref_rpm: float) -> None:
        self.client.set_setpoint(enable=True, mode=int(Mode.SPEED), reference=ref_rpm * RPM_TO_RAD_S,
                                 controller_id=self.controller_id)

    # --- the period ---------------------------------------------------------------------------------
    def _run(self, out: LoopOutcome, stopped: list[int]) -> bool:
        """The periods, until the end of the run, a protective ending or a stop request (`stopped` truthy: then
        True)."""
        ts_s, ts_ns, realtime = self.cfg.ts_s, self.cfg.ts_ns, self._realtime
        pace, follow_reference, sample_and_send = self._pace, self._follow_reference, self._sample_and_send
        apply_and_trace, accept, record = self._apply_and_trace, self._accept, self._record
        delayed = self.faulty is not None and not realtime and self.faulty.spec.delays
        await_command = self._await_delayed if delayed else self._await_command
        check_end, flush, block = self._check_end, self._flush, self.BLOCK
        check, tolerate = self._check_contract, self.cfg.tolerate
        for k in range(self._n_total):
            if stopped:
                return True
            t = k * ts_s
            if realtime:
                pace(out)
            follow_reference(t)
            smp, extra = sample_and_send(k, t)
            st = apply_and_trace(k)
            pending = self._pending
            reply = await_command(k & 0xFFFF)
            if self._wait_end is not None:  # the wait for this period's Command ended the run, no verdict on it
                if self._wait_end is WaitEnd.INTERRUPTED:
                    return True
                self._host_stall_end(out, k)
                break
            cmd = check(out, k, reply)
            watchdog = accept(cmd, k, out)
            record(out, t, k, smp, st, pending, extra, cmd is None)
            if out.violation_count > tolerate:
                v = out.violations[-1] if out.violation_count <= MAX_KEPT_VIOLATIONS else None
                reason = v.message() if v is not None else f"{out.violation_count} DUT contract violations"
                self._end(out, EndCode.DUT_VIOLATION, f"{reason}; inverter put in the safe state")
                break
            if watchdog:
                silent = self._silent
                self._end(out, EndCode.SAFETY_STOP,
                          f"watchdog: target silent for {silent} periods ({silent * ts_s * 1e3:.1f} ms); inverter "
                          f"put in the safe state (zero vector, all lower switches on)")
                break
            self._next_start += ts_ns
            if (k + 1) % block == 0:
                flush(out)
            if check_end(out, k, smp, st, extra):
                break
        return False

    def _pace(self, out: LoopOutcome) -> None:
        """Real time: busy-wait for the period start and record how late it began [ns]."""
        next_start = self._next_start
        now = time.perf_counter_ns()
        while now < next_start:
            now = time.perf_counter_ns()
        late = now - next_start
        out.lateness_ns.append(late)
        if late > self._overrun_ns:
            out.overruns += 1

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
        self.clock_s = t
        tap = self._tap
        if tap is not None:
            tap.t, tap.seq = t, k
        self.client.send_measurement(meas)
        return smp, extra

    def _apply_and_trace(self, k: int) -> PeriodStats:
        """Advance the plant one period with the pending command; keep the trace of the metrics window."""
        pending = self._pending
        if pending.duties:  # duty-cycle command: the carrier comparison (src/pmsm_hil/hil/pwm.py)
            st = self.plant.advance(*applied_sequence(pending, self._ts_ns, carrier_half(self._pwm_update, k)))
        elif pending.mirror:  # symmetric command: s0..s(n-1), s(n-2)..s0 (same durations)
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
        """Command `seq`: polled until the deadline (real time), the lockstep timeout (another process: of its own
        time when the host observes it, `LockstepWait`) or at once (in-process target, which answers inside the
        poll)."""
        poll_command = self._poll_command
        cmd = poll_command(seq)
        if cmd is not None or (not self._realtime and self.inproc_result is not None):
            return cmd
        if not self._realtime:
            lockstep = self._lockstep
            cmd, end = lockstep.wait(lambda: poll_command(seq), self._stop_asked)
            self._wait_ns = int(lockstep.wait_s * 1e9)
            if end in (WaitEnd.HOST_STALL, WaitEnd.INTERRUPTED):
                self._wait_end = end
            return cmd
        t0 = time.perf_counter_ns()
        deadline = self._next_start + self.cfg.ts_ns
        now = t0
        while cmd is None and now < deadline:
            cmd = poll_command(seq)
            now = time.perf_counter_ns()
        self._wait_ns = now - t0
        return cmd

    def _await_delayed(self, seq: int) -> Command | None:
        """Lockstep with delayed frames (`--fault delay/jitter`): virtual time runs from the period start to
        its deadline through the release times of the delayed frames (a reply computed the moment its
        Measurement arrives), so a Command is in time when up + down delay ≤ Ts (zero compute time). A target
        in another process gets the lockstep timeout for its reply, as without faults (`LockstepWait`)."""
        faulty = self.faulty
        assert faulty is not None
        deadline_s = self.clock_s + self.cfg.ts_s + 1e-12  # release times are sums of floats: 1 ps slack
        poll_command = self._poll_command
        lockstep = self._lockstep
        waiting = False
        cmd = None
        while cmd is None:
            cmd = poll_command(seq)
            if cmd is not None:
                break
            nxt = faulty.next_release_s()
            if nxt is not None and nxt <= deadline_s:
                self.clock_s = max(self.clock_s, nxt)  # the next delayed frame arrives
                continue
            if self.inproc_result is not None:
                return None
            if not waiting:
                lockstep.begin()
                waiting = True
                continue
            end = lockstep.judge(self._stop_asked)
            if end is WaitEnd.MISSING:
                cmd = poll_command(seq)
                break
            if end is not None:
                self._wait_end = end
                break
        if waiting:
            lockstep.finish()
            self._wait_ns = int(lockstep.wait_s * 1e9)
        return cmd

    def _check_contract(self, out: LoopOutcome, k: int, cmd: Command | None) -> Command | None:
        """Record the period's contract findings; the Command if it may be applied, else None."""
        findings = self._take_anomalies()
        wait = self._wait_ns
        if wait:
            out.max_wait_ns = max(out.max_wait_ns, wait)
            self._wait_ns = 0
        if cmd is not None:
            bad = check_command(cmd, self._ts_ns, self._max_state)
            if bad is not None:
                findings.append((bad[0], describe(cmd), bad[1]))
                cmd = None
        else:  # no genuine reply (whatever else arrived)
            if self._realtime:
                limit = "before the next period start (real time)"
            elif self.inproc_result is not None:
                limit = "from the in-process target"
            else:
                limit = f"within the lockstep timeout {self.cfg.lockstep_timeout_s:g} s ({self._lockstep.clock_words})"
            findings.append((MISSING, "Command", f"no Command for seq {k & 0xFFFF} {limit}"))
        for rule, frame, detail in findings:
            out.violation_count += 1
            out.violations_by_rule[rule] = out.violations_by_rule.get(rule, 0) + 1
            if len(out.violations) < MAX_KEPT_VIOLATIONS:
                out.violations.append(Violation(k, k & 0xFFFF, rule, frame, detail))
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
        states3 = (*applied.states, 0, 0, 0)[:3]
        durs3 = (*applied.durations_ns, 0, 0, 0)[:3]
        load_t = self._load_value(t)[0]
        periods.pack_into(
            periods.buf, periods.end,
            t, k, smp.i_a, smp.i_b, smp.i_c, smp.i_d, smp.i_q, smp.torque, smp.omega_m, smp.theta_e,
            self._pending_tref, self._speed_ref_rpm * RPM_TO_RAD_S, load_t, n_st, *states3, *durs3,
            applied.vector_id, applied.candidates, applied.exec_time_ns, *self._pending_split,
            st.leg_transitions, st.boundary_transitions, st.narrow_pulses, 0, int(missed),
            st.narrow_pulses_gated, applied.mirror, *extra, *_flat_duties(applied))
        periods.end += periods.size
        out.completed_periods = k + 1
        self._pending, self._pending_split, self._pending_tref = self._next_pending

    def _check_end(self, out: LoopOutcome, k: int, smp: Any, st: PeriodStats, extra: tuple[float, ...]) -> bool:
        """Target fault or plant trip (instantaneous overcurrent/overspeed): safe state, True to stop."""
        if self.client.faults:
            f = self.client.faults[0]
            self._end(out, EndCode.SAFETY_STOP,
                      f"target fault code {f.code} (detail {f.detail}); inverter put in the safe state")
            return True
        plant, i_trip, w_trip = self.plant, self._i_trip, self._w_trip
        if (abs(smp.i_a) > i_trip or abs(smp.i_b) > i_trip or abs(smp.i_c) > i_trip
                or abs(smp.omega_m) > w_trip or (self._second_set_trip and max(abs(x) for x in extra[:3]) > i_trip)
                or st.peak_current_a > i_trip):
            reason = plant.check_trips(smp) or (
                f"overcurrent: peak |i| = {st.peak_current_a:.2f} A inside the period > i_trip = {i_trip:.2f} A")
            self._end(out, EndCode.SAFETY_STOP, f"plant trip: {reason}; inverter put in the safe state (zero vector)")
            return True
        trip = plant.check_trips() if k == self._n_total - 1 else None
        if trip is not None:
            self._end(out, EndCode.SAFETY_STOP, f"plant trip: {trip}; inverter put in the safe state (zero vector)")
            return True
        return False

    def _host_stall_end(self, out: LoopOutcome, k: int) -> None:
        """The host kept the target from running for the whole host-stall limit while period k waited for its
        Command: the host's error (exit 1), not the firmware's."""
        clock = self._lockstep.clock
        out.error = host_stall_error(clock.pid if clock is not None else 0, self._lockstep.wait_s,
                                     f"the Command of period {k}", self.cfg.host_stall_limit_s)
        self._end(out, EndCode.INTERNAL_ERROR, f"{out.error}; inverter put in the safe state")

    def _end(self, out: LoopOutcome, code: EndCode, reason: str) -> None:
        """Record how the run ends; every ending but completion puts the plant in the safe state."""
        out.end_code = int(code)
        out.end_reason = reason
        out.safe_state = True

    def _stop(self, out: LoopOutcome) -> None:
        """Every exit path: the zero vector (all lower switches on) after a protective ending, and the
        disabling Setpoint to the target (recorded as a frame when frames are logged), confirmed by the target
        (src/pmsm_hil/hil/runner/safe_stop.py; unconfirmed: the zero vector now, and the ending says so)."""
        if out.safe_state:
            with contextlib.suppress(Exception):
                self.plant.advance((0,), (self.cfg.ts_ns,))
        if self.faulty is not None:  # the safe stop is not subject to the injected faults
            if self._tap is not None:
                self._tap.link = self.faulty.link
            else:
                self.client.link = self.faulty.link
        clock = self.own_time(SAFE_STOP_TIMEOUT_S)
        if settle_ending(out, disable_and_confirm(self.client, self.controller_id, clock=clock,
                                                  stall_limit_s=self.cfg.host_stall_limit_s)):
            with contextlib.suppress(Exception):
                self.plant.advance((0,), (self.cfg.ts_ns,))


def run_reference_loop(cfg: RunConfig, conn: TargetConnection, cid: int, sink: RunSink) -> LoopOutcome:
    """The run through the Python loop feeding `sink` block by block (the last block, with the frames of the safe
    stop, is flushed whatever ended the loop): `--loop python` in the test suite."""
    spec = cfg.fault_spec
    plant = build_plant(cfg)
    loop = ClosedLoop(cfg, plant, conn.client, cid, inproc_result=conn.inproc_result,
                      record_frames=sink.logger is not None, sink=sink,
                      first_duties=tuple(duty_value(duty_raw(d)) for d in conn.duties_at_start(plant.sample())),
                      own_time=conn.own_time)
    faulty = install_faults(conn.client, spec, loop.run_time_s) if spec is not None else None
    loop.faulty = sink.faulty = faulty
    outcome = loop.run()
    if faulty is not None:
        outcome.link_faults = dict(faulty.counts)
    outcome.trace = sink.window.tail.array()
    return outcome
