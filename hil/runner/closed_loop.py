"""The closed loop: plant ↔ target each control period, in lockstep (virtual time) or real time."""

from __future__ import annotations

import contextlib
import gc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S, DynoMechanics
from pmsm_hil.hil.plant_base import PlantBase
from pmsm_hil.hil.runner.phases import NO_SIX_PHASE, measurement6, phase_setup
from pmsm_hil.hil.runner.recorder import ByteRecords, FrameTap, frame_records, period_records
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.hil.sensors import SensorModel
from pmsm_hil.protocol.ids import Mode
from pmsm_hil.protocol.messages import Command, Measurement, Measurement6

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
    """One run of the plant against a target through a TargetClient."""

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

    def _run(self) -> LoopOutcome:
        cfg, plant, client = self.cfg, self.plant, self.client
        sc = cfg.scenario
        ts_s, ts_ns = cfg.ts_s, cfg.ts_ns
        n_total = round(sc.total_s / ts_s)
        n_settle = round(sc.settle_s / ts_s)
        rows_per_period = math.ceil(ts_s / cfg.trace_dt_s) + 1
        setup = phase_setup(cfg)
        six = setup.legs == 6
        trace = np.zeros((n_total - n_settle) * rows_per_period, dtype=setup.trace_dtype)
        trace.view(np.uint8)[:] = 0  # touch every page now, not inside the paced loop
        trace_view = trace.view(np.float64).reshape(-1, setup.trace_columns)
        out = LoopOutcome(period_records(), frame_records(), trace, n_settle)
        out.periods.reserve(n_total)
        out.frames.reserve(4 * n_total)
        periods = out.periods
        periods_pack_into, periods_buf, rec_size = periods.pack_into, periods.buf, periods.size
        tap: FrameTap | None = None
        if self.record_frames:
            tap = FrameTap(client.link, out.frames)
            client.link = tap
        dyno = isinstance(plant.mechanics, DynoMechanics)
        realtime = cfg.mode == "realtime"
        zero_cmd = Command(seq=0, states=(0,), durations_ns=(ts_ns,))
        pending = zero_cmd
        pending_split = (0, 0, 0)
        pending_tref = _NAN
        silent = 0
        trace_n = 0
        speed_ref_rpm = sc.speed_reference_rpm(0.0)
        client.set_setpoint(enable=True, mode=int(Mode.SPEED), reference=speed_ref_rpm * RPM_TO_RAD_S,
                            controller_id=self.controller_id)
        load = sc.load_profile()
        sensors = self.sensors
        ideal_sensors = cfg.sensors.ideal
        vdc = cfg.motor.vdc
        i_trip = cfg.motor.i_trip
        w_trip = cfg.motor.speed_trip_rpm * RPM_TO_RAD_S
        send_measurement, poll_command = client.send_measurement, client.poll_command
        inproc = self.inproc_result
        timeout_ns = int(cfg.lockstep_timeout_s * 1e9)
        t_wall0 = time.perf_counter_ns()
        next_start = t_wall0
        for k in range(n_total):
            t = k * ts_s
            if realtime:
                now = time.perf_counter_ns()
                while now < next_start:
                    now = time.perf_counter_ns()
                out.lateness_ns.append(now - next_start)
            ref = sc.speed_reference_rpm(t)
            if ref != speed_ref_rpm:
                speed_ref_rpm = ref
                client.set_setpoint(enable=True, mode=int(Mode.SPEED), reference=ref * RPM_TO_RAD_S,
                                    controller_id=self.controller_id)
                if dyno:
                    plant.mechanics = DynoMechanics(ref)
            smp = plant.sample()
            seq = k & 0xFFFF
            meas: Measurement | Measurement6
            if six:
                meas = measurement6(seq, smp, sensors, ideal_sensors, vdc)
                extra = (smp.i_u, smp.i_v, smp.i_w, smp.i_x, smp.i_y)
            else:
                if ideal_sensors:
                    ia, ib, ic, th = smp.i_a, smp.i_b, smp.i_c, smp.theta_e
                else:
                    ia, ib, ic = sensors.currents(smp.i_a, smp.i_b, smp.i_c)
                    th = sensors.angle(smp.theta_e)
                meas = Measurement(seq=seq, i_a=ia, i_b=ib, i_c=ic, theta_e=th, omega_m=smp.omega_m, vdc=vdc)
                extra = NO_SIX_PHASE
            if tap is not None:
                tap.t, tap.seq = t, k
            send_measurement(meas)
            if pending.mirror:  # symmetric command: s0..s(n-1), s(n-2)..s0 (same durations)
                st = plant.advance(*pending.expanded())
            else:
                st = plant.advance(pending.states, pending.durations_ns)
            if k >= n_settle:
                tr = plant.last_trace
                n_rows = tr.shape[0]
                trace_view[trace_n:trace_n + n_rows] = tr
                trace_n += n_rows
            n_st = len(pending.states)
            states3 = (*pending.states, 0, 0)[:3]
            durs3 = (*pending.durations_ns, 0, 0)[:3]
            load_t = load.value_and_slope(t)[0]
            # wait for command k
            cmd = poll_command(seq)
            late = 0
            if cmd is None:
                if realtime:
                    deadline = next_start + ts_ns
                    while cmd is None and time.perf_counter_ns() < deadline:
                        cmd = poll_command(seq)
                elif inproc is None:
                    deadline = time.perf_counter_ns() + timeout_ns
                    while cmd is None and time.perf_counter_ns() < deadline:
                        cmd = poll_command(seq)
            missed = 0
            watchdog = False
            if cmd is None:
                missed = 1
                silent += 1
                out.lost_commands += 1
                if realtime:
                    out.deadline_misses += 1
                watchdog = silent >= cfg.watchdog_periods
                next_cmd = zero_cmd if cfg.miss_policy == "zero" else pending
                next_split, next_tref = pending_split, pending_tref
            else:
                silent = 0
                next_cmd = cmd
                res = inproc() if inproc is not None else None
                if res is not None:
                    next_split = res.split_ns  # type: ignore[attr-defined]
                    next_tref = res.torque_ref  # type: ignore[attr-defined]
                    full_miss = getattr(res, "full_miss", 255)
                    if full_miss != 255 and k >= n_settle:
                        out.candidate_checked += 1
                        out.candidate_misses += full_miss
                else:
                    next_split, next_tref = (0, 0, 0), _NAN
            periods_pack_into(
                periods_buf, periods.end,
                t, k, smp.i_a, smp.i_b, smp.i_c, smp.i_d, smp.i_q, smp.torque, smp.omega_m, smp.theta_e,
                pending_tref, speed_ref_rpm * RPM_TO_RAD_S, load_t, n_st, *states3, *durs3,
                pending.vector_id, pending.candidates, pending.exec_time_ns, *pending_split,
                st.leg_transitions, st.boundary_transitions, st.narrow_pulses, late, missed,
                st.narrow_pulses_gated, pending.mirror, *extra)
            periods.end += rec_size
            if watchdog:
                out.completed_periods = k + 1
                out.end_reason = (f"watchdog: target silent for {silent} periods "
                                  f"({silent * ts_s * 1e3:.1f} ms); inverter put in the safe state "
                                  f"(zero vector, all lower switches on)")
                self._safe_state(out)
                break
            pending, pending_split, pending_tref = next_cmd, next_split, next_tref
            next_start += ts_ns
            out.completed_periods = k + 1
            if self.sink is not None and (k + 1) % self.BLOCK == 0:
                self.sink(out.periods, out.frames, None)
            if client.faults:
                f = client.faults[0]
                out.end_reason = f"target fault code {f.code} (detail {f.detail}); inverter put in the safe state"
                self._safe_state(out)
                break
            if (abs(smp.i_a) > i_trip or abs(smp.i_b) > i_trip or abs(smp.i_c) > i_trip
                    or abs(smp.omega_m) > w_trip or (six and max(abs(x) for x in extra[:3]) > i_trip)
                    or st.peak_current_a > i_trip):
                reason = plant.check_trips(smp) or (
                    f"overcurrent: peak |i| = {st.peak_current_a:.2f} A inside the period > i_trip = {i_trip:.2f} A")
                out.end_reason = f"plant trip: {reason}; inverter put in the safe state (zero vector)"
                self._safe_state(out)
                break
            trip = plant.check_trips() if k == n_total - 1 else None
            if trip is not None:
                out.end_reason = f"plant trip: {trip}; inverter put in the safe state (zero vector)"
                self._safe_state(out)
                break
        out.wall_time_s = (time.perf_counter_ns() - t_wall0) / 1e9
        out.late_commands = client.stale_commands
        out.trace = trace[:trace_n]
        return out

    def _safe_state(self, out: LoopOutcome) -> None:
        """Zero vector (all lower switches on) and the target disabled."""
        out.safe_state = True
        self.plant.advance((0,), (self.cfg.ts_ns,))
        with contextlib.suppress(Exception):
            self.client.set_setpoint(enable=False, mode=int(Mode.SPEED), reference=0.0,
                                     controller_id=self.controller_id)
