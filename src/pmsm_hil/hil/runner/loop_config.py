"""What the native loop needs to know of a run, written once into its nl_config_t, whose sub-structs are
RunConfig's groups (run_groups.py): machine (the plant's kernel structs, trip limits), operation (periods, the
scenario's speed-reference changes and load profile), target and link (codec scales and limits from hil.dbc, the
DUT contract's limits, lockstep observation), timing and real time, sensors, outputs (frame records, trace)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.machine import Machine, MachineLayout, MeasurementFrames
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S
from pmsm_hil.hil.plant_base import KernelView, PlantBase
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.run_groups import OperationGroup, TargetLinkGroup, TimingGroup
from pmsm_hil.hil.runner.scenario import Scenario
from pmsm_hil.hil.sensors import SensorConfig
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


def fill_codec(codec: Any, lib: Any, frames: MeasurementFrames, fd: bool) -> None:
    """The Measurement's frames (CAN FD or classic parts, format) and their scales and raw limits (hil.dbc) into
    nl_codec_cfg_t `codec`."""
    codec.fd = 1 if fd else 0
    codec.meas_format = getattr(lib, frames.native)
    cur = frames.current_layout.signal("i_a")
    meas_b = frames.state_layout
    th, w, v = meas_b.signal("theta_e"), meas_b.signal("omega_m"), meas_b.signal("vdc")
    codec.s_i, codec.i_min, codec.i_max = cur.scale, cur.raw_min, cur.raw_max
    codec.s_th, codec.th_mod = th.scale, th.raw_max + 1
    codec.s_w, codec.w_min, codec.w_max = w.scale, w.raw_min, w.raw_max
    codec.s_v, codec.v_min, codec.v_max = v.scale, v.raw_min, v.raw_max


def fill_config(c: Any, ffi: Any, lib: Any, cfg: RunConfig, plant: PlantBase, controller_id: int, fd: bool,
                opts: NativeOptions, *, shared_bus: bool = False) -> list[Any]:
    """Write everything of the run into the loop's nl_config_t `c`, one group at a time from RunConfig's groups;
    ParameterError for a machine kind the native loop cannot run (never run as another machine). The link itself
    (`attach`) and the load FMU come when the run starts. Returns the buffers `c` points to (load profile, plant
    scratch): keep them alive for the run."""
    layout = cfg.machine.layout
    problem = machine_kernel_problem(layout)
    if problem is not None:
        raise ParameterError(f"--loop native: {problem}")
    view = plant.kernel_view()
    if view.kernel == 0:
        raise ParameterError(f"--loop native: the {type(plant).__name__} plant has no machine-kernel table")
    timing = cfg.timing
    c.nan = math.nan
    scratch = fill_machine(c.machine, ffi, cfg.machine, plant, view, timing.adc_delay_ns)
    load_t, load_v = fill_operation(c.operation, ffi, cfg.operation, timing.ts_s, view.inertia)
    fill_target_link(c.target_link, ffi, lib, cfg.target_link, layout, controller_id, fd, opts, shared_bus)
    fill_timing(c.timing, timing)
    fill_sensors(c.sensors, cfg.sensors, cfg.motor.pole_pairs)
    fill_outputs(c.outputs, ffi, view, len(plant.TRACE_COLUMNS), opts.record_frames)
    return [load_t, load_v, scratch]


def fill_machine(m: Any, ffi: Any, machine: Machine, plant: PlantBase, view: KernelView, adc_delay_ns: int) -> Any:
    """The machine group: legs, highest gate code, the kernel table and the plant's structs, a scratch copy of its
    state when the ADC instant is inside the period (returned: keep it alive), DC link [V], trip limits."""
    motor = machine.params
    m.legs, m.max_state = machine.layout.legs, machine.layout.max_state_code
    m.kernel = ffi.cast("mk_kernel_t *", view.kernel)
    m.plant_params, m.plant_state = ffi.cast("void *", view.params), ffi.cast("void *", view.state)
    scratch = ffi.new("char[]", plant.state_bytes) if adc_delay_ns > 0 else ffi.NULL
    m.plant_scratch = scratch  # a copy of the plant state advanced to the ADC instant (loop.c sample_adc)
    m.vdc = motor.vdc
    m.i_trip, m.w_trip = motor.i_trip, motor.speed_trip_rpm * RPM_TO_RAD_S
    return scratch


def fill_operation(o: Any, ffi: Any, operation: OperationGroup, ts_s: float, inertia: bool) -> tuple[Any, Any]:
    """The scenario and load group: periods, mechanics, the load profile (its arrays returned: keep them alive) and
    the speed reference's changes. The load FMU (`open_load_fmu`) replaces the profile when the run starts."""
    sc = operation.scenario
    n_total = round(sc.total_s / ts_s)
    o.n_total, o.n_settle = n_total, round(sc.settle_s / ts_s)
    o.rpm_to_rad_s = RPM_TO_RAD_S
    o.dyno, o.inertia = 1 if sc.mechanics == "dyno" else 0, 1 if inertia else 0
    points = sc.load_profile().points
    o.n_load = len(points)
    load_t = ffi.new("double[]", [t for t, _ in points] or [0.0])
    load_v = ffi.new("double[]", [v for _, v in points] or [0.0])
    o.load_t, o.load_v = load_t, load_v
    changes = reference_changes(sc, ts_s, n_total)
    o.n_ref = len(changes)
    for j, (k, rpm) in enumerate(changes):
        o.ref_k[j], o.ref_rpm[j] = k, rpm
    return load_t, load_v


def fill_target_link(t: Any, ffi: Any, lib: Any, target_link: TargetLinkGroup, layout: MachineLayout,
                     controller_id: int, fd: bool, opts: NativeOptions, shared_bus: bool) -> None:
    """The target and link group: codec, controller, DUT contract, the target's process or emulated MCU the
    lockstep waits observe, a shared bus, a Fault the set-up left, the duties before the first Command. The link
    and its lockstep timeout come with the link's `attach` at the run's start."""
    fill_codec(t.codec, lib, layout.measurement, fd)
    t.controller_id, t.mode_speed = controller_id, int(Mode.SPEED)
    t.tolerate, t.watchdog_periods = target_link.tolerate, target_link.watchdog_periods
    t.target_pid = opts.target_pid  # host stalls (loop_stall.h): the target's own time counts
    t.stall_limit_ns = int(target_link.host_stall_limit_s * 1e9)
    if opts.guest_insns_address:  # an emulated MCU: its own progress counts (nl_guest_available)
        t.guest_insns = ffi.cast("const uint64_t *", opts.guest_insns_address)
        t.guest_ns_per_insn = opts.guest_ns_per_insn
    t.shared_bus = 1 if shared_bus else 0
    t.fault_pending = 1 if opts.fault is not None else 0
    t.fault_code_in, t.fault_detail_in = opts.fault if opts.fault is not None else (0, 0)
    if opts.first_duties and len(opts.first_duties) != layout.legs:
        raise ParameterError(f"the target's duties before its first Command are {len(opts.first_duties)}, the "
                             f"machine has {layout.legs} legs")
    t.first_n_duties = len(opts.first_duties)
    for j, d in enumerate(opts.first_duties):
        t.first_duty_raw[j] = duty_raw(d)


def fill_timing(t: Any, timing: TimingGroup) -> None:
    """The timing and real-time group: Ts, PWM update, ADC instant, lockstep or real time with its miss policy,
    overrun threshold, spin window, SCHED_FIFO priority, CPU and memory lock."""
    t.ts_ns, t.ts_s = timing.ts_ns, timing.ts_s
    t.pwm_double = 1 if timing.pwm_update == "double" else 0  # duty-cycle Commands
    t.adc_delay_ns = timing.adc_delay_ns
    t.realtime = 1 if timing.mode == "realtime" else 0
    t.miss_zero = 1 if timing.miss_policy == "zero" else 0
    t.overrun_ns = timing.overrun_threshold_ns
    t.spin_ns = SPIN_NS_FIFO if timing.rt_priority and rt_throttled() else SPIN_NS
    t.rt_priority = timing.rt_priority
    t.cpu = -1 if timing.cpu is None else timing.cpu
    t.lock_memory = 1 if timing.mode == "realtime" else 0


def fill_sensors(s: Any, sensors: SensorConfig, pole_pairs: int) -> None:
    """The sensors group: ideal or noise [A], ADC step [A], encoder step [rad electrical] (0: ideal angle)."""
    s.ideal = 1 if sensors.ideal else 0
    s.noise_std, s.adc_lsb = sensors.noise_std_a, sensors.adc_lsb_a
    s.two_pi = 2.0 * math.pi
    s.enc_step = s.two_pi * pole_pairs / sensors.encoder_counts if sensors.encoder_counts else 0.0


def fill_outputs(o: Any, ffi: Any, view: KernelView, trace_columns: int, record_frames: bool) -> None:
    """The outputs group: frame records on or off, the plant's trace buffer, rows per period, step [s], columns."""
    o.record_frames = 1 if record_frames else 0
    o.plant_trace = ffi.cast("double *", view.trace)
    o.trace_cap, o.trace_dt, o.trace_columns = view.trace_cap, view.trace_dt_s, trace_columns


def rt_throttled() -> bool:
    """True when the kernel throttles real-time tasks (sched_rt_runtime_us ≥ 0, the default 950 000 µs per s):
    a SCHED_FIFO loop must then sleep part of each period. With `sysctl kernel.sched_rt_runtime_us=-1` it may
    busy-wait the whole period, as without `--rt-priority`."""
    try:
        with open(RT_RUNTIME_FILE, encoding="ascii") as f:
            return int(f.read().strip()) >= 0
    except (OSError, ValueError):
        return True
