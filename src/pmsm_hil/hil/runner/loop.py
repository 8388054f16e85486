"""`NativeLoop`: the run's period loop in C (src/pmsm_hil/hil/runner/c/loop.c), Python for everything around it.
The loop reaches its target through one C link (`attach`: the C target core in process, a wire, or the callback
link through Python).

The C loop runs in its own thread over the whole run (the GIL released) and fills a ring of blocks; this
thread drains each full block to the run's sink (window metrics, speed check, live view, logger) — the same
period records, raw frames and trace rows as `ClosedLoop` — and hands the block back with the sensor noise of
a later one. Set-up and the safe stop (configuration, the enabling and the disabling Setpoint, the zero
vector) go through `TargetClient` over the same link, as with any target.
"""

from __future__ import annotations

import contextlib
import gc
import threading
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from pmsm_hil.hil.load_fmu.errors import LoadFmuStepError
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S, DynoMechanics
from pmsm_hil.hil.plant_base import PlantBase
from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE
from pmsm_hil.hil.runner import recorder
from pmsm_hil.hil.runner.callback_link import NativePyLink
from pmsm_hil.hil.runner.contract import MISSING, RULES, EndCode
from pmsm_hil.hil.runner.core_link import NativeCoreLink
from pmsm_hil.hil.runner.cpu_isolation import isolate_cpu
from pmsm_hil.hil.runner.lockstep_wait import host_stall_error, lockstep_clock_words
from pmsm_hil.hil.runner.loop_config import NativeOptions, fill_config
from pmsm_hil.hil.runner.loop_findings import internal_error, violation
from pmsm_hil.hil.runner.loop_load_fmu import load_fmu_failed, open_load_fmu
from pmsm_hil.hil.runner.loop_outcome import MAX_KEPT_VIOLATIONS, BlockSink, LoopOutcome
from pmsm_hil.hil.runner.recorder import FrameTap, frame_records, period_records
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.safe_stop import SAFE_STOP_TIMEOUT_S, disable_and_confirm, settle_ending
from pmsm_hil.hil.runner.stop_request import StopRequest, deferred_interrupts
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.hil.runner.target_time import target_time
from pmsm_hil.hil.runner.wire import NativeWireLink
from pmsm_hil.hil.sensors import SensorModel
from pmsm_hil.protocol.ids import Mode, ParamId
from pmsm_hil.protocol.links.shared_bus import bus_starved_reason
from pmsm_hil.protocol.links.spec import redact_spec

_WAIT_NS = 50_000_000  # drain wait per try (Ctrl-C is seen between tries) [ns]


class _TripSample(NamedTuple):
    """What `PlantBase.check_trips` reads of a sample, rebuilt from a period record."""

    phase_currents: tuple[float, ...]
    omega_m: float


class NativeLoop:
    """One run of the plant against the C target core through the C period loop (`run` as `ClosedLoop.run`)."""

    def __init__(self, cfg: RunConfig, plant: PlantBase, client: TargetClient,
                 link: NativeCoreLink | NativeWireLink | NativePyLink, controller_id: int, opts: NativeOptions, *,
                 sink: BlockSink | None = None) -> None:
        self.cfg = cfg
        self.plant = plant
        self.client = client
        self.link = link
        self.controller_id = controller_id
        self.opts = opts
        self.sink = sink
        self.sensors = SensorModel(cfg.sensors, cfg.motor.pole_pairs)
        ffi, lib = link.ffi, link.lib
        self._ffi, self._lib = ffi, lib
        self._mem = ffi.new("char[]", int(lib.nl_handle_size()))
        self._h = ffi.cast("nl_handle_t *", self._mem)
        if lib.nl_init(self._h) != 0:
            raise MemoryError("native loop: cannot initialise its mutex and condition variable")
        self._c = lib.nl_config(self._h)
        self._res = lib.nl_result(self._h)
        self._config_arrays = fill_config(self._c, ffi, lib, cfg, plant, controller_id, link.fd, opts,
                                          shared_bus=client.shared)
        try:
            self.load_fmu = open_load_fmu(cfg, ffi, lib, self._c)  # None: the scenario's load profile
        except BaseException:
            lib.nl_destroy(self._h)
            raise
        if lib.NL_FINDINGS < MAX_KEPT_VIOLATIONS:
            raise ImportError("native loop: NL_FINDINGS must keep at least MAX_KEPT_VIOLATIONS findings per block")
        self._period_size = int(lib.nl_sizeof_period())
        self._frame_size = int(lib.nl_sizeof_frame())
        if self._period_size != PERIOD_DTYPE.itemsize or self._frame_size != FRAME_DTYPE.itemsize:
            raise ImportError("native loop records are out of step with src/pmsm_hil/hil/records.py dtypes")
        columns = len(plant.TRACE_COLUMNS)
        rows = lib.NL_BLOCK * max(int(self._c.outputs.trace_cap), 1)
        self._traces = [np.zeros((rows, columns)) for _ in range(lib.NL_RING)]  # pages touched before the run
        for i, tr in enumerate(self._traces):
            slot = lib.nl_slot(self._h, i)
            slot.trace = ffi.cast("double *", tr.ctypes.data)
            slot.trace_rows_cap = rows
        self._noise_per_block = (cfg.machine.phases * lib.NL_BLOCK
                                 if not cfg.sensors.ideal and cfg.sensors.noise_std_a else 0)
        self._trace_dtype = cfg.machine.layout.trace_dtype
        self._blocks_filled = 0
        self._drained = 0
        self._last_period: Any = None

    def run(self) -> LoopOutcome:
        """The whole run (settle + metrics window, or until a protective ending), then the safe stop.

        Ctrl-C and SIGTERM are deferred (`deferred_interrupts`): they stop the C loop (`nl_stop`), and the drain
        goes on until the loop has ended and every full block went to the sink, so the log holds every period
        counted."""
        with deferred_interrupts() as stop:
            return self._run(stop)

    def completed_periods(self) -> int:
        """Periods the C loop has completed so far, read while it runs (the counter it sets each period; for a
        display: the blocks drained carry the records)."""
        return int(self._res.completed_periods)

    def _run(self, stop: StopRequest) -> LoopOutcome:
        lib, h = self._lib, self._h
        gc_was_enabled = gc.isenabled()
        gc.collect()
        gc.disable()
        out = self._start()
        self.link.attach(self._c, self.cfg.lockstep_timeout_s)  # the link as the enabling Setpoint left it
        if isinstance(self.link, NativePyLink):  # a bus error in a callback ends the run
            self.link.on_error = lambda: lib.nl_stop(h)
        thread = threading.Thread(target=lib.nl_run, args=(h,), name="hil-native-loop", daemon=True)
        interrupted = False
        restore_cpus = self._isolate_cpu()
        try:
            for _ in range(lib.NL_RING):
                self._hand_back(self._blocks_filled % lib.NL_RING)
            with stop.hook(self._stop_loop):
                thread.start()
                self._drain(out)
        except KeyboardInterrupt:  # a handler of the caller's own (signals are deferred only where they raise)
            interrupted = True
        except Exception as exc:  # the sink failed: still a safe stop and complete outputs
            out.error = exc
        finally:
            self._stop_loop()
            while thread.is_alive():
                thread.join(0.05)
            restore_cpus()
            with contextlib.suppress(Exception):
                self._drain(out)
            self._finish(out, interrupted or stop.requested)  # a stop asked by a signal ends as interrupted
            self._stop(out)
            out.wall_time_s = (time.perf_counter_ns() - self._t_wall0) / 1e9
            try:
                self._flush(out, None, 0)
            finally:
                lib.nl_destroy(h)
                if self.load_fmu is not None:
                    out.load_fmu = self.load_fmu.metrics()
                    self.load_fmu.close()
                if gc_was_enabled:
                    gc.enable()
        return out

    def _stop_loop(self) -> None:
        """Stop the C loop, and any wait of it for the load FMU's process (that may never answer)."""
        self._lib.nl_stop(self._h)
        if self.load_fmu is not None:
            self.load_fmu.stop()

    # --- set-up -------------------------------------------------------------------------------------
    def _isolate_cpu(self) -> Callable[[], None]:
        """Real time on `--cpu N`: this process's other threads and the logger process leave CPU N for the run."""
        cfg = self.cfg
        if cfg.mode != "realtime" or cfg.cpu is None:
            return lambda: None
        pid = getattr(getattr(self.sink, "logger", None), "pid", None)  # a RunSink's logger process
        return isolate_cpu(cfg.cpu, [pid] if isinstance(pid, int) else [])

    def _start(self) -> LoopOutcome:
        n_total = int(self._c.operation.n_total)
        keep = n_total <= recorder.KEEP_PERIODS_MAX  # read now (tests lower it)
        out = LoopOutcome(period_records(keep=keep), frame_records(keep=False), np.zeros(0, self._trace_dtype),
                          int(self._c.operation.n_settle))
        self._tap: FrameTap | None = None
        if self.opts.record_frames:
            self._tap = FrameTap(self.client.link, out.frames)
            self.client.link = self._tap
        self._t_wall0 = time.perf_counter_ns()
        ref0 = float(self._c.operation.ref_rpm[0])
        if self.load_fmu is not None and self.cfg.scenario.preset_integrator:  # bumpless start on the FMU's torque
            self.client.configure({ParamId.TORQUE_INTEGRATOR_INIT: self.load_fmu.torque0})
        self.client.set_setpoint(enable=True, mode=int(Mode.SPEED), reference=ref0 * RPM_TO_RAD_S,
                                 controller_id=self.controller_id)
        return out

    # --- the ring -----------------------------------------------------------------------------------
    def _hand_back(self, i: int) -> None:
        """Fill slot i with the sensor noise of the next block to run and give it to the loop."""
        n = self._noise_per_block
        if n:
            noise = self.sensors.take_noise(n)
            self._ffi.memmove(self._lib.nl_slot_noise(self._h, i), noise.tobytes(), noise.nbytes)
        self._blocks_filled += 1
        self._lib.nl_release(self._h, i)

    def _drain(self, out: LoopOutcome) -> None:
        """Hand every full block to the sink until the loop has ended and the ring is empty."""
        lib, h = self._lib, self._h
        ring = lib.NL_RING
        while True:
            i = self._drained % ring
            got = lib.nl_wait_full(h, i, _WAIT_NS)
            if got < 0:
                return
            if got == 0:
                continue
            self._drained += 1
            try:
                self._take_block(out, i)
            finally:
                self._hand_back(i)

    def _take_block(self, out: LoopOutcome, i: int) -> None:
        lib, ffi, h = self._lib, self._ffi, self._h
        slot = lib.nl_slot(h, i)
        n = int(slot.n_periods)
        out.periods.reserve(n)
        out.periods.append_packed(memoryview(ffi.buffer(lib.nl_slot_periods(h, i), n * self._period_size)))
        n_frames = int(slot.n_frames)
        if n_frames:
            out.frames.append_packed(memoryview(ffi.buffer(lib.nl_slot_frames(h, i), n_frames * self._frame_size)))
        if self.cfg.mode == "realtime" and n:
            lateness = np.frombuffer(ffi.buffer(lib.nl_slot_lateness(h, i), 8 * n), dtype=np.int64)
            out.lateness_us.add(lateness.copy())
        limit = self._missing_limit()
        findings = lib.nl_slot_findings(h, i)
        for j in range(int(slot.n_findings)):
            if len(out.violations) < MAX_KEPT_VIOLATIONS:
                out.violations.append(violation(findings[j], lib, limit))
        self._flush(out, self._traces[i], int(slot.n_trace_rows))

    def _flush(self, out: LoopOutcome, trace: np.ndarray | None, rows: int) -> None:
        periods = out.periods.take()
        if periods.shape[0]:
            self._last_period = periods[-1].copy()
        frames = out.frames.take() if self.opts.record_frames else None
        rec = np.zeros(0, self._trace_dtype) if trace is None else trace[:rows].view(self._trace_dtype).reshape(-1)
        if self.sink is not None:
            self.sink(periods, frames, rec)

    def _missing_limit(self) -> str:
        if self.cfg.mode == "realtime":
            return "before the next period start (real time)"
        if self._other_process():
            clock = lockstep_clock_words(self.opts.target_pid, bool(self.opts.guest_insns_address))
            return f"within the lockstep timeout {self.cfg.lockstep_timeout_s:g} s ({clock})"
        return "from the in-process target"

    # --- the ending ---------------------------------------------------------------------------------
    def _finish(self, out: LoopOutcome, interrupted: bool) -> None:
        """Counters and the ending from the C loop, worded as `ClosedLoop` words them."""
        lib, res, cfg = self._lib, self._res, self.cfg
        out.completed_periods = int(res.completed_periods)
        out.paced_time_s = int(res.wall_ns) / 1e9
        out.lost_commands, out.deadline_misses = int(res.lost_commands), int(res.deadline_misses)
        out.late_commands, out.overruns = int(res.stale_commands), int(res.overruns)
        out.realtime_sync_us = int(res.sync_ns) / 1e3 if int(res.sync_ns) >= 0 else None
        out.max_wait_ns = int(res.max_wait_ns)
        out.host_stalls, out.host_stall_s = int(res.host_stalls), int(res.host_stall_ns) / 1e9
        out.violation_count = int(res.violation_count)
        out.violations_by_rule = {rule: int(res.by_rule[j]) for j, rule in enumerate(RULES) if res.by_rule[j]}
        out.candidate_checked, out.candidate_misses = int(res.candidate_checked), int(res.candidate_misses)
        out.ring_waits = int(res.ring_waits)
        if cfg.mode == "realtime":  # the C loop's own lateness histogram (1 µs bins), counted per period in C
            out.lateness_hist_1us = np.frombuffer(self._ffi.buffer(res.late_hist), dtype=np.int64).copy()
        self._add_link_counters()
        self._add_bus_counters(out)
        self.link.rt_errnos = (int(res.rt_mlock_errno), int(res.rt_sched_errno), int(res.rt_affinity_errno))
        if self._tap is not None:
            self._tap.t, self._tap.seq = float(res.tap_t), int(res.tap_seq)
        if cfg.scenario.mechanics == "dyno":  # the Python object follows what the C loop set
            self.plant.mechanics = DynoMechanics(float(res.speed_ref_rpm))
        end = int(res.end)
        if isinstance(self.link, NativePyLink) and self.link.error is not None and out.error is None:
            out.error = self.link.error  # a bus error in the callback link
        if out.error is not None:
            self._end(out, EndCode.INTERNAL_ERROR, f"internal error: {type(out.error).__name__}: {out.error}")
        elif interrupted or end == lib.NL_END_INTERRUPTED:
            self._end(out, EndCode.INTERRUPTED, "interrupted (Ctrl-C or SIGTERM)")
        elif end == lib.NL_END_HOST_STALL:
            out.error = host_stall_error(self.opts.target_pid, int(res.host_stall_wait_ns) / 1e9,
                                         f"the Command of period {int(res.end_period)}", cfg.host_stall_limit_s)
            self._end(out, EndCode.INTERNAL_ERROR, f"{out.error}; inverter put in the safe state")
        elif (bus := self._bus_starved(out, end)) is not None:  # other nodes' frames kept the Commands out
            self._take_back_missing(out, end)
            self._end(out, EndCode.SAFETY_STOP, f"{bus}; inverter put in the safe state")
        elif end == lib.NL_END_VIOLATION:
            v = out.violations[-1] if out.violation_count <= MAX_KEPT_VIOLATIONS else None
            reason = v.message() if v is not None else f"{out.violation_count} DUT contract violations"
            self._end(out, EndCode.DUT_VIOLATION, f"{reason}; inverter put in the safe state")
        elif end == lib.NL_END_WATCHDOG:
            silent = int(res.silent)
            self._end(out, EndCode.SAFETY_STOP,
                      f"watchdog: target silent for {silent} periods ({silent * cfg.ts_s * 1e3:.1f} ms); inverter "
                      f"put in the safe state (zero vector, all lower switches on)")
        elif end == lib.NL_END_FAULT:
            hint = ""
            if int(res.fault_code) == 6:  # not_implemented: the firmware does not have the controller selected
                hint = (f": the firmware does not implement controller '{cfg.controller}' (a firmware of your own "
                        "runs as --controller external)")
            self._end(out, EndCode.SAFETY_STOP, f"target fault code {int(res.fault_code)} (detail "
                                                f"{int(res.fault_detail)}){hint}; inverter put in the safe state")
        elif end == lib.NL_END_TRIP:
            self._trip(out)
        elif (fmu_failure := load_fmu_failed(self.load_fmu, res, lib)) is not None:
            if self.load_fmu is not None and self.load_fmu.contained_failure:  # its process crashed or hung
                self._end(out, EndCode.SAFETY_STOP, f"{fmu_failure}; inverter put in the safe state (zero vector)")
                return
            out.error = LoadFmuStepError(fmu_failure)
            self._end(out, EndCode.INTERNAL_ERROR, f"{fmu_failure}; inverter put in the safe state")
        elif end in (lib.NL_END_PLANT_ERROR, lib.NL_END_ENCODE_ERROR):
            out.error = internal_error(res, lib, cfg.machine.phases)
            self._end(out, EndCode.INTERNAL_ERROR, f"internal error: {type(out.error).__name__}: {out.error}")
        elif out.completed_periods == int(self._c.operation.n_total):
            trip = self.plant.check_trips()
            if trip is not None:
                self._end(out, EndCode.SAFETY_STOP,
                          f"plant trip: {trip}; inverter put in the safe state (zero vector)")

    def _trip(self, out: LoopOutcome) -> None:
        """A trip found in period end_period: the reason from the plant, as `ClosedLoop._check_end`."""
        rec = self._last_period
        legs = self.cfg.machine.phases
        currents = (rec["i_a"], rec["i_b"], rec["i_c"], rec["i_u"], rec["i_v"], rec["i_w"])[:legs]
        smp = _TripSample(tuple(float(x) for x in currents), float(rec["omega_m"]))
        i_trip = self.cfg.motor.i_trip
        peak = float(self._res.peak_current)
        reason = self.plant.check_trips(smp) or (
            f"overcurrent: peak |i| = {peak:.2f} A inside the period > i_trip = {i_trip:.2f} A")
        self._end(out, EndCode.SAFETY_STOP, f"plant trip: {reason}; inverter put in the safe state (zero vector)")

    def _add_bus_counters(self, out: LoopOutcome) -> None:
        """A shared bus: other nodes' frames of the set-up (TargetClient) and of the loop (C) in `out`."""
        if not self._c.target_link.shared_bus:
            return
        res, bus = self._res, self.client.bus
        out.bus_foreign_frames = bus.foreign + int(res.bus_foreign_frames)
        out.bus_suspect_frames = bus.suspect + int(res.bus_suspect_frames)

    def _take_back_missing(self, out: LoopOutcome, end: int) -> None:
        """The bus, not the target, ended the run: the `missing` finding that ended it is not the target's (the
        Command was kept out by other nodes' frames), so it leaves the findings and their counts."""
        if end != self._lib.NL_END_VIOLATION or not out.violations or out.violations[-1].rule != MISSING:
            return
        out.violations.pop()
        out.violation_count -= 1
        left = out.violations_by_rule.get(MISSING, 0) - 1
        if left > 0:
            out.violations_by_rule[MISSING] = left
        else:
            out.violations_by_rule.pop(MISSING, None)

    def _bus_starved(self, out: LoopOutcome, end: int) -> str | None:
        """The reason naming the bus when the run ended for want of Commands (the watchdog, or rule `missing`)
        while other nodes' frames came at BUS_STARVE_FPS or more since the last Command; else None."""
        lib, res = self._lib, self._res
        missing = end == lib.NL_END_VIOLATION and bool(out.violations) and out.violations[-1].rule == MISSING
        if not self._c.target_link.shared_bus or not (end == lib.NL_END_WATCHDOG or missing):
            return None
        seq = int(res.end_period) & 0xFFFF
        mode = "real time" if self.cfg.mode == "realtime" else "lockstep"
        link = redact_spec(self.cfg.link)
        waiting_for = (f"{mode}: no Command for seq {seq} {self._missing_limit()}; {out.bus_foreign_frames} foreign "
                       f"and {out.bus_suspect_frames} suspect frame(s) in the run")
        posing = int(res.bus_host_silent)
        if posing:  # another node sent the host's frames (a Setpoint disables or reconfigures the target)
            return (f"bus {link}: {posing} frame(s) of the host's ids (Setpoint, ConfigParam, Measurement) from "
                    f"another node since the last Command reached the target too ({waiting_for})")
        return bus_starved_reason(link, int(res.bus_silent_frames), int(res.bus_silent_ns) / 1e9, waiting_for)

    def _add_link_counters(self) -> None:
        res = self._res
        self.link.detach()  # the link's own counters, frames included
        dec = self.client.decoder.stats
        for name in ("frames", "messages", "unknown_id", "bad_length", "bad_value", "stale", "duplicate",
                     "out_of_order", "mixed_seq"):
            setattr(dec, name, getattr(dec, name) + int(getattr(res, f"dec_{name}")))
        # every ConfigAck in the run came after its parameter was acknowledged (configure returned): an answer to a
        # resend, as TargetClient counts the ones it drains itself
        self.client.config_acks_repeated += int(res.dec_config_acks)

    def _other_process(self) -> bool:
        """The target answers over wall time (another process or a board), not inside the loop's call."""
        return self.link.other_process

    @staticmethod
    def _end(out: LoopOutcome, code: EndCode, reason: str) -> None:
        out.end_code = int(code)
        out.end_reason = reason
        out.safe_state = True

    def _stop(self, out: LoopOutcome) -> None:
        """The zero vector after a protective ending and the confirmed disabling Setpoint (as `ClosedLoop._stop`)."""
        if out.safe_state:
            with contextlib.suppress(Exception):
                self.plant.advance((0,), (self.cfg.ts_ns,))
        if isinstance(self.link, NativePyLink):  # the safe stop is not subject to the injected faults
            self.link.remove_faults()
        clock = target_time(self.opts.target_pid, SAFE_STOP_TIMEOUT_S,
                            (self.opts.guest_insns_address, self.opts.guest_ns_per_insn))
        if settle_ending(out, disable_and_confirm(self.client, self.controller_id, clock=clock,
                                                  stall_limit_s=self.cfg.host_stall_limit_s)):
            with contextlib.suppress(Exception):
                self.plant.advance((0,), (self.cfg.ts_ns,))
