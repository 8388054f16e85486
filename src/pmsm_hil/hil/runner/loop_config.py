"""What the native loop needs to know of a run, written once into its nl_config_t: periods, the DUT
contract's limits, the sensor model, the codec's scales and limits (from hil.dbc), the plant's kernel structs,
the scenario's speed-reference changes and load profile, and the real-time options."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.machine import MachineLayout, MeasurementFrames
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S
from pmsm_hil.hil.plant_base import PlantBase
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import Scenario
from pmsm_hil.protocol.codec_duty import duty_raw
from pmsm_hil.protocol.ids import Mode

#: real time: the loop busy-waits at most this long before a period start and sleeps before that [ns]
SPIN_NS = 100_000
#: ... under SCHED_FIFO (`--rt-priority`: timer slack 0, wake-ups within microseconds): sleeping most of the period
#: also keeps the thread under the kernel's real-time throttling (sched_rt_runtime_us: 95 % of each second)
SPIN_NS_FIFO = 70_000
#: the kernel's real-time budget per period (-1: real-time tasks are not throttled)
RT_RUNTIME_FILE = "/proc/sys/kernel/sched_rt_runtime_us"


@dataclass(frozen=True, slots=True)
class NativeOptions:
    """How the native loop runs beside the RunConfig: frames recorded, a Fault the target sent while being
    configured (code, detail), the target's process."""

    record_frames: bool
    fault: tuple[int, int] | None = None
    #: the target's process the loop observes in lockstep (host stalls; 0: none, the timeout is wall time)
    target_pid: int = 0
    #: an emulated MCU's running instruction count (its address in this process, 0: none) and the virtual time of
    #: one instruction [ns]: its lockstep time is its own progress
    guest_insns_address: int = 0
    guest_ns_per_insn: int = 0
    #: the duties of period 0, before the target's first reply (a board's outputs at the run's start; empty: the
    #: full-period zero vector)
    first_duties: tuple[float, ...] = ()


def reference_changes(sc: Scenario, ts_s: float, n_total: int) -> list[tuple[int, float]]:
    """(first period, speed reference [rpm]) of each value `ClosedLoop._follow_reference` would send: the
    reference at t = k·Ts [s] of the scenario's one speed step, found with the same float expressions."""
    ref = sc.speed_reference_rpm
    changes = [(0, ref(0.0))]
    if sc.speed_step_s is None:
        return changes
    final = ref(math.inf)
    k = max(0, math.ceil(sc.speed_step_s / ts_s))
    while k > 0 and ref((k - 1) * ts_s) == final:
        k -= 1
    while k < n_total and ref(k * ts_s) != final:
        k += 1
    if k < n_total and final != changes[0][1]:
        changes.append((k, final))
    return changes


def support_problem(cfg: RunConfig, lib: Any) -> str | None:
    """Why this run cannot use the native loop, None when it can."""
    return machine_kernel_problem(cfg.machine.layout)


def machine_kernel_problem(layout: MachineLayout) -> str | None:
    """Why the native loop cannot run this machine kind (no machine-kernel table, or Measurement frames with
    another number of currents than its legs), None when it can."""
    if layout.native_kernel is None:
        return (f"machine kind '{layout.kind}' has no native kernel ({layout.plant_class.__name__}.KERNEL_TABLE is "
                "None): the native loop never runs it as another machine")
    if layout.measurement.currents != layout.legs:
        return (f"machine kind '{layout.kind}': its Measurement frames carry {layout.measurement.currents} currents "
                f"for {layout.legs} legs")
    return None


def fill_codec(c: Any, lib: Any, frames: MeasurementFrames) -> None:
    """The Measurement format and its scales and raw limits (hil.dbc) into nl_config_t `c`."""
    c.meas_format = getattr(lib, frames.native)
    cur = frames.current_layout.signal("i_a")
    meas_b = frames.state_layout
    th, w, v = meas_b.signal("theta_e"), meas_b.signal("omega_m"), meas_b.signal("vdc")
    c.s_i, c.i_min, c.i_max = cur.scale, cur.raw_min, cur.raw_max
    c.s_th, c.th_mod = th.scale, th.raw_max + 1
    c.s_w, c.w_min, c.w_max = w.scale, w.raw_min, w.raw_max
    c.s_v, c.v_min, c.v_max = v.scale, v.raw_min, v.raw_max


def fill_config(c: Any, ffi: Any, lib: Any, cfg: RunConfig, plant: PlantBase, controller_id: int, fd: bool,
                opts: NativeOptions) -> list[Any]:
    """Write everything of the run into the loop's nl_config_t `c`; ParameterError for a machine kind the
    native loop cannot run (never run as another machine). Returns the arrays `c` points to (the load profile):
    keep them alive for the run."""
    sc, m, sensors = cfg.scenario, cfg.motor, cfg.sensors
    layout = cfg.machine.layout
    problem = machine_kernel_problem(layout)
    if problem is not None:
        raise ParameterError(f"--loop native: {problem}")
    legs = layout.legs
    n_total = round(sc.total_s / cfg.ts_s)
    c.legs, c.fd = legs, 1 if fd else 0
    c.ts_ns, c.ts_s = cfg.ts_ns, cfg.ts_s
    c.n_total, c.n_settle = n_total, round(sc.settle_s / cfg.ts_s)
    c.max_state, c.tolerate, c.watchdog_periods = cfg.machine.layout.max_state_code, cfg.tolerate, cfg.watchdog_periods
    c.miss_zero = 1 if cfg.miss_policy == "zero" else 0
    c.pwm_double = 1 if cfg.pwm_update == "double" else 0  # duty-cycle Commands
    c.controller_id, c.mode_speed = controller_id, int(Mode.SPEED)
    c.record_frames = 1 if opts.record_frames else 0
    c.nan = math.nan
    c.ideal = 1 if sensors.ideal else 0
    c.noise_std, c.adc_lsb = sensors.noise_std_a, sensors.adc_lsb_a
    c.two_pi = 2.0 * math.pi
    c.enc_step = c.two_pi * m.pole_pairs / sensors.encoder_counts if sensors.encoder_counts else 0.0
    c.vdc = m.vdc
    fill_codec(c, lib, layout.measurement)
    view = plant.kernel_view()
    if view.kernel == 0:
        raise ParameterError(f"--loop native: the {type(plant).__name__} plant has no machine-kernel table")
    c.kernel = ffi.cast("mk_kernel_t *", view.kernel)
    c.plant_params, c.plant_state = ffi.cast("void *", view.params), ffi.cast("void *", view.state)
    c.plant_trace = ffi.cast("double *", view.trace)
    c.adc_delay_ns = cfg.adc_delay_ns
    scratch = ffi.new("char[]", plant.state_bytes) if cfg.adc_delay_ns > 0 else ffi.NULL
    c.plant_scratch = scratch  # a copy of the plant state advanced to the ADC instant (loop.c sample_adc)
    c.trace_cap, c.trace_dt, c.trace_columns = view.trace_cap, view.trace_dt_s, len(plant.TRACE_COLUMNS)
    c.rpm_to_rad_s = RPM_TO_RAD_S
    c.dyno, c.inertia = 1 if sc.mechanics == "dyno" else 0, 1 if view.inertia else 0
    points = sc.load_profile().points
    c.n_load = len(points)
    load_t = ffi.new("double[]", [t for t, _ in points] or [0.0])
    load_v = ffi.new("double[]", [v for _, v in points] or [0.0])
    c.load_t, c.load_v = load_t, load_v
    changes = reference_changes(sc, cfg.ts_s, n_total)
    c.n_ref = len(changes)
    for j, (k, rpm) in enumerate(changes):
        c.ref_k[j], c.ref_rpm[j] = k, rpm
    c.i_trip, c.w_trip = m.i_trip, m.speed_trip_rpm * RPM_TO_RAD_S
    c.fault_pending = 1 if opts.fault is not None else 0
    if opts.first_duties and len(opts.first_duties) != legs:
        raise ParameterError(f"the target's duties before its first Command are {len(opts.first_duties)}, the "
                             f"machine has {legs} legs")
    c.first_n_duties = len(opts.first_duties)
    for j, d in enumerate(opts.first_duties):
        c.first_duty_raw[j] = duty_raw(d)
    c.fault_code_in, c.fault_detail_in = opts.fault if opts.fault is not None else (0, 0)
    c.realtime = 1 if cfg.mode == "realtime" else 0
    c.overrun_ns, c.spin_ns = cfg.overrun_threshold_ns, SPIN_NS_FIFO if cfg.rt_priority and rt_throttled() else SPIN_NS
    c.rt_priority = cfg.rt_priority
    c.cpu = -1 if cfg.cpu is None else cfg.cpu
    c.lock_memory = 1 if cfg.mode == "realtime" else 0
    return [load_t, load_v, scratch]


def rt_throttled() -> bool:
    """True when the kernel throttles real-time tasks (sched_rt_runtime_us ≥ 0, the default 950 000 µs per s):
    a SCHED_FIFO loop must then sleep part of each period. With `sysctl kernel.sched_rt_runtime_us=-1` it may
    busy-wait the whole period, as without `--rt-priority`."""
    try:
        with open(RT_RUNTIME_FILE, encoding="ascii") as f:
            return int(f.read().strip()) >= 0
    except (OSError, ValueError):
        return True
