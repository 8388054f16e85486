"""What the native loop needs to know of a run, written once into its nl_config_t: periods, the DUT
contract's limits, the sensor model, the codec's scales and limits (from hil.dbc), the plant's kernel structs,
the scenario's speed-reference changes and load profile, and the real-time options."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pmsm_hil.hil.mechanics import RPM_TO_RAD_S
from pmsm_hil.hil.plant_base import PlantBase
from pmsm_hil.hil.runner.native_link_kinds import NATIVE_WIRES
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import Scenario
from pmsm_hil.protocol import codec6
from pmsm_hil.protocol.codec import L_MEAS_A, L_MEAS_B
from pmsm_hil.protocol.ids import Mode
from pmsm_hil.protocol.links.spec import parse_spec

#: real time: the loop busy-waits at most this long before a period start and sleeps before that [ns]
SPIN_NS = 100_000
#: ... under SCHED_FIFO (`--rt-priority`: timer slack 0, wake-ups within microseconds): sleeping most of the period
#: also keeps the thread under the kernel's real-time throttling (sched_rt_runtime_us: 95 % of each second)
SPIN_NS_FIFO = 70_000
#: the kernel's real-time budget per period (-1: real-time tasks are not throttled)
RT_RUNTIME_FILE = "/proc/sys/kernel/sched_rt_runtime_us"


@dataclass(frozen=True, slots=True)
class NativeOptions:
    """How the native loop runs beside the RunConfig: frames recorded, a target silent after this many
    Measurements (fault injection of the tests, None: never), a Fault the target sent while being
    configured (code, detail)."""

    record_frames: bool
    silent_after: int | None = None
    fault: tuple[int, int] | None = None


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
    kind = parse_spec(cfg.link).kind
    in_process = cfg.target in ("auto", "inproc") and kind == "virtual"
    spawned = cfg.target in ("auto", "spawn", "external") or cfg.sil_isolated  # SIL: its own process
    over_link = spawned and kind.lower() in NATIVE_WIRES
    if not (in_process or over_link):
        target = cfg.target.partition(":")[0]
        return (f"the native loop runs the in-process target on the virtual link or a spawned or external target "
                f"on a {'/'.join(NATIVE_WIRES)} link (here: a {kind} link, {target} target)")
    if cfg.fault_spec is not None:
        return "link fault injection (--fault) runs on the Python link"
    sc = cfg.scenario
    if len(sc.load_profile().points) > lib.NL_LOAD_POINTS:
        return f"the load profile has more than {lib.NL_LOAD_POINTS} points"
    return None


def fill_codec(c: Any, legs: int) -> None:
    """The Measurement's scales and raw limits of `legs` phases (hil.dbc) into nl_config_t `c`."""
    cur = (codec6.L_MEAS6_A if legs == 6 else L_MEAS_A).signal("i_a")
    meas_b = codec6.L_MEAS6_B if legs == 6 else L_MEAS_B
    th, w, v = meas_b.signal("theta_e"), meas_b.signal("omega_m"), meas_b.signal("vdc")
    c.s_i, c.i_min, c.i_max = cur.scale, cur.raw_min, cur.raw_max
    c.s_th, c.th_mod = th.scale, th.raw_max + 1
    c.s_w, c.w_min, c.w_max = w.scale, w.raw_min, w.raw_max
    c.s_v, c.v_min, c.v_max = v.scale, v.raw_min, v.raw_max


def fill_config(c: Any, ffi: Any, cfg: RunConfig, plant: PlantBase, controller_id: int, fd: bool,
                opts: NativeOptions) -> None:
    """Write everything of the run into the loop's nl_config_t `c`."""
    sc, m, sensors = cfg.scenario, cfg.motor, cfg.sensors
    legs = cfg.machine.phases
    n_total = round(sc.total_s / cfg.ts_s)
    c.legs, c.fd = legs, 1 if fd else 0
    c.ts_ns, c.ts_s = cfg.ts_ns, cfg.ts_s
    c.n_total, c.n_settle = n_total, round(sc.settle_s / cfg.ts_s)
    c.max_state, c.tolerate, c.watchdog_periods = cfg.machine.layout.max_state_code, cfg.tolerate, cfg.watchdog_periods
    c.miss_zero = 1 if cfg.miss_policy == "zero" else 0
    c.controller_id, c.mode_speed = controller_id, int(Mode.SPEED)
    c.silent_after = -1 if opts.silent_after is None else opts.silent_after
    c.record_frames = 1 if opts.record_frames else 0
    c.nan = math.nan
    c.ideal = 1 if sensors.ideal else 0
    c.noise_std, c.adc_lsb = sensors.noise_std_a, sensors.adc_lsb_a
    c.two_pi = 2.0 * math.pi
    c.enc_step = c.two_pi * m.pole_pairs / sensors.encoder_counts if sensors.encoder_counts else 0.0
    c.vdc = m.vdc
    fill_codec(c, legs)
    view = plant.kernel_view()
    c.plant_params, c.plant_state = ffi.cast("void *", view.params), ffi.cast("void *", view.state)
    c.plant_trace = ffi.cast("double *", view.trace)
    c.trace_cap, c.trace_dt, c.trace_columns = view.trace_cap, view.trace_dt_s, len(plant.TRACE_COLUMNS)
    c.torque_k, c.psi_f, c.dl = 1.5 * m.pole_pairs, m.psi_f, m.ld - m.lq
    c.sqrt3_2, c.rpm_to_rad_s = math.sqrt(3.0) / 2.0, RPM_TO_RAD_S
    c.dyno, c.inertia = 1 if sc.mechanics == "dyno" else 0, 1 if view.inertia else 0
    points = sc.load_profile().points
    c.n_load = len(points)
    for j, (t, v) in enumerate(points):
        c.load_t[j], c.load_v[j] = t, v
    changes = reference_changes(sc, cfg.ts_s, n_total)
    c.n_ref = len(changes)
    for j, (k, rpm) in enumerate(changes):
        c.ref_k[j], c.ref_rpm[j] = k, rpm
    c.i_trip, c.w_trip = m.i_trip, m.speed_trip_rpm * RPM_TO_RAD_S
    c.fault_pending = 1 if opts.fault is not None else 0
    c.fault_code_in, c.fault_detail_in = opts.fault if opts.fault is not None else (0, 0)
    c.realtime = 1 if cfg.mode == "realtime" else 0
    c.overrun_ns, c.spin_ns = cfg.overrun_threshold_ns, SPIN_NS_FIFO if cfg.rt_priority and rt_throttled() else SPIN_NS
    c.rt_priority = cfg.rt_priority
    c.cpu = -1 if cfg.cpu is None else cfg.cpu
    c.lock_memory = 1 if cfg.mode == "realtime" else 0


def rt_throttled() -> bool:
    """True when the kernel throttles real-time tasks (sched_rt_runtime_us ≥ 0, the default 950 000 µs per s):
    a SCHED_FIFO loop must then sleep part of each period. With `sysctl kernel.sched_rt_runtime_us=-1` it may
    busy-wait the whole period, as without `--rt-priority`."""
    try:
        with open(RT_RUNTIME_FILE, encoding="ascii") as f:
            return int(f.read().strip()) >= 0
    except (OSError, ValueError):
        return True
