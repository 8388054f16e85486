"""What the three- and six-phase plants share: validation, buffers, mechanics, period advance."""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from typing import Any, ClassVar, NamedTuple

import numpy as np
import numpy.typing as npt

from pmsm_hil.hil import _plant_native
from pmsm_hil.hil.control_period import PLANT_MIN_TS_S, check_control_period
from pmsm_hil.hil.errors import ParameterError, PlantFaultError, SequenceError
from pmsm_hil.hil.machine_params import MachineParams
from pmsm_hil.hil.mechanics import DynoMechanics, InertiaMechanics, LoadProfile, Mechanics, TwoMassMechanics

#: Sub-intervals one period may hold: the 13 segments of six duty cycles (src/pmsm_hil/hil/pwm.py) fit.
MAX_SUBINTERVALS = 16
#: Load-profile breakpoints honoured inside one control period (more are a ParameterError).
MAX_LOAD_BREAKPOINTS = 8


class PeriodStats(NamedTuple):
    """Inverter events of one advanced period (counts of leg gate transitions and pulses) and the largest
    phase-current magnitude seen at the trace rows [A] (0 with the trace off): what a hardware
    overcurrent comparator sees, including peaks inside the period. Field order = the C stats struct."""

    leg_transitions: int
    boundary_transitions: int
    narrow_pulses: int
    suppressed_pulses: int
    open_phase_events: int
    narrow_pulses_gated: int
    peak_current_a: float
    trace_rows: int
    error: int = 0


class KernelView(NamedTuple):
    """The plant's C structs and trace buffer as addresses, for a native loop that advances the same plant:
    the machine-kernel table (src/pmsm_hil/hil/kernels/machine_kernel.h, 0: the plant has none), params, state and
    trace-buffer addresses, trace rows one period may write, trace step [s] (0: none), and whether the load
    profile applies (inertia mode)."""

    kernel: int
    params: int
    state: int
    trace: int
    trace_cap: int
    trace_dt_s: float
    inertia: bool


#: Layout of pl_period_stats_t / p6_period_stats_t (identical by construction; checked at import).
_STATS_STRUCT = struct.Struct("=6Idii")


def set_inverter_pmsm_params(p: Any, params: Any) -> None:
    """The fields the PMSM kernels' params structs share (pl_params_t / p6_params_t): motor and inverter
    parameters [SI] (the mechanics are PlantBase's)."""
    p.rs, p.ld, p.lq, p.psi_f, p.vdc = params.rs, params.ld, params.lq, params.psi_f, params.vdc
    p.t_dead, p.t_mpw = params.t_dead, params.t_mpw
    p.pole_pairs = params.pole_pairs


def reset_gate_edges(s: Any, legs: int) -> None:
    """No gate edge and no dead time yet on any of `legs` legs (the gate_edges.c state of an inverter kernel)."""
    for leg in range(legs):
        s.legs.last_edge_t[leg] = -1.0
        s.legs.dead_until[leg] = -1.0


class PlantBase:
    """One control period at a time through a C kernel; subclasses name the kernel and its structs.

    Subclass attributes: ``NATIVE_MODULE`` (the cffi extension holding the kernel, default the bundled
    `pmsm_hil.hil._plant_native`), ``KERNEL_PREFIX`` (C struct/function prefix, e.g. "pl": the structs
    ``<prefix>_params_t``, ``<prefix>_state_t``, ``<prefix>_period_stats_t``), ``KERNEL_TABLE`` (the name of the
    extension's function returning its machine-kernel table for the native loop; None: the Python loop only),
    ``LEGS``, ``MAX_STATE`` (largest state code), ``STATE_FORMAT`` (how codes are written, for errors) and
    ``TRACE_COLUMNS``; ``_kernel_advance`` is the C function (a staticmethod); ``_set_kernel_params`` writes the
    machine's parameters into the params struct.
    """

    NATIVE_MODULE: ClassVar[Any] = _plant_native
    KERNEL_TABLE: ClassVar[str | None] = None
    KERNEL_PREFIX: ClassVar[str]
    LEGS: ClassVar[int]
    MAX_STATE: ClassVar[int]
    STATE_FORMAT: ClassVar[str]
    TRACE_COLUMNS: ClassVar[tuple[str, ...]]

    def __init__(self, params: Any, ts_s: float, mechanics: Mechanics, *, theta0_rad: float = 0.0,
                 trace_dt_s: float | None = 2e-6, max_piece_s: float = 5e-6) -> None:
        self.ts_ns = check_control_period(ts_s, "control period 'ts'", PLANT_MIN_TS_S)
        if trace_dt_s is not None and not (0 < trace_dt_s <= ts_s):
            raise ParameterError(f"'trace_dt' must be in (0, ts], got {trace_dt_s} s")
        if not math.isfinite(theta0_rad):
            raise ParameterError("'theta0' must be finite")
        self.params: MachineParams = params
        self.ts_s = ts_s
        self.trace_dt_s = trace_dt_s
        self._max_piece_s = max_piece_s
        prefix = self.KERNEL_PREFIX
        ffi = self._ffi = self.NATIVE_MODULE.ffi
        self._p: Any = ffi.new(f"{prefix}_params_t *")
        self._s: Any = ffi.new(f"{prefix}_state_t *")
        self._stats: Any = ffi.new(f"{prefix}_period_stats_t *")
        if ffi.sizeof(self._stats[0]) != _STATS_STRUCT.size:
            raise ImportError(f"{prefix}_period_stats_t does not match the Python stats layout")
        self._stats_buf = ffi.buffer(self._stats)
        self._inertia = False
        self._states = ffi.new("int32_t[]", MAX_SUBINTERVALS)
        self._durations = ffi.new("int64_t[]", MAX_SUBINTERVALS)
        self._load_bp = ffi.new("double[]", 3 * MAX_LOAD_BREAKPOINTS)
        self._load_c: Any = ffi.new("mech_load_t *")
        self._load_c.bp = self._load_bp
        #: the kernel state's mechanics (mech_state_t *), kept: sample() reads the speed every period
        self._mech_s: Any = ffi.addressof(self._s, "mech")
        columns = len(self.TRACE_COLUMNS)
        rows = 0 if trace_dt_s is None else math.ceil(ts_s / trace_dt_s) + 2
        self._trace_cap = rows
        self._trace_buf = ffi.new("double[]", max(rows, 1) * columns)
        self._trace_np: npt.NDArray[np.float64] = np.frombuffer(
            ffi.buffer(self._trace_buf), dtype=np.float64).reshape(-1, columns)
        self._trace_dt = 0.0 if trace_dt_s is None else trace_dt_s
        self._trace_ptr = self._trace_buf if trace_dt_s is not None else ffi.NULL
        self._load = LoadProfile.constant(0.0)
        self._set_kernel_params(params)
        self._p.mech.j, self._p.mech.b, self._p.mech.max_piece = params.j, params.b, max_piece_s
        self.mechanics = mechanics
        self._s.theta_e = theta0_rad % (2.0 * math.pi)
        if isinstance(mechanics, InertiaMechanics | TwoMassMechanics):
            omega0 = mechanics.initial_speed_rpm * 2.0 * math.pi / 60.0
            self._s.mech.omega_m, self._s.mech.omega_l, self._s.mech.twist = omega0, omega0, 0.0
        self._init_kernel_state()

    def _set_kernel_params(self, params: Any) -> None:
        """Write the machine's parameters into the kernel's params struct ``self._p``."""
        raise NotImplementedError

    def _init_kernel_state(self) -> None:
        """Kernel state beyond angle and speed at the start (default: none)."""

    def _kernel_advance(self, *args: Any) -> int:
        raise NotImplementedError

    @property
    def mechanics(self) -> Mechanics:
        """Current mechanical mode."""
        return self._mechanics

    @mechanics.setter
    def mechanics(self, mechanics: Mechanics) -> None:
        lib, mech = self.NATIVE_MODULE.lib, self._p.mech
        if isinstance(mechanics, DynoMechanics):
            lib.mech_hold(self._p_mech, self._s_mech, mechanics.omega_m)
            self._inertia = False
            self._load_c.value, self._load_c.slope, self._load_c.n_bp = 0.0, 0.0, 0
        elif isinstance(mechanics, InertiaMechanics):
            mech.mode, mech.j = lib.MECH_INERTIA, self.params.j
            self._inertia = True
            self._load = mechanics.load
        elif isinstance(mechanics, TwoMassMechanics):
            mech.mode = lib.MECH_TWO_MASS
            mech.j, mech.j_load = mechanics.j_motor, mechanics.j_load
            mech.k_shaft, mech.c_shaft = mechanics.k_shaft, mechanics.c_shaft
            self._s.mech.omega_l, self._s.mech.twist = self._s.mech.omega_m, 0.0
            self._inertia = True
            self._load = mechanics.load
        else:
            raise ParameterError(f"unknown mechanics mode {mechanics!r}")
        self._mechanics = mechanics

    @property
    def _p_mech(self) -> Any:
        """The kernel's mechanics params (mech_params_t *)."""
        return self._ffi.addressof(self._p, "mech")

    @property
    def _s_mech(self) -> Any:
        """The kernel's mechanics state (mech_state_t *)."""
        return self._mech_s

    @property
    def load_speed(self) -> float:
        """Load-side speed [rad/s]: with a two-mass shaft the load mass's, else the rotor's."""
        s = self._s.mech
        return float(s.omega_l if isinstance(self._mechanics, TwoMassMechanics) else s.omega_m)

    @property
    def shaft_twist(self) -> float:
        """Shaft twist, rotor angle minus load angle [rad] (0 unless a two-mass shaft)."""
        return float(self._s.mech.twist)

    def _set_common_state(self, theta_e: float | None, omega_m: float | None, gate: int | None,
                          **currents: float | None) -> None:
        if gate is not None:
            if not 0 <= gate <= self.MAX_STATE:
                raise SequenceError(f"gate code {gate} outside 0..{self.MAX_STATE}")
            self._s.gate = gate
        for name, value in currents.items():
            if value is not None:
                setattr(self._s, name, value)
        if theta_e is not None:
            self._s.theta_e = theta_e % (2.0 * math.pi)
        if omega_m is not None:
            self._s.mech.omega_m = omega_m

    @property
    def time_s(self) -> float:
        """Plant time [s]."""
        return int(self._s.t_ns) / 1e9

    @property
    def gate(self) -> int:
        """Gate code currently applied."""
        return int(self._s.gate)

    def advance(self, states: Sequence[int], durations_ns: Sequence[int]) -> PeriodStats:
        """Apply one control period's switching sequence: state codes and durations [ns] summing to Ts."""
        n = len(states)
        if n == 0 or n > MAX_SUBINTERVALS or len(durations_ns) != n:
            raise SequenceError(
                f"switching sequence needs 1..{MAX_SUBINTERVALS} states with one duration each, "
                f"got {n} states and {len(durations_ns)} durations")
        total = 0
        max_state = self.MAX_STATE
        c_states, c_durations = self._states, self._durations
        for k in range(n):
            st, du = states[k], durations_ns[k]
            if not 0 <= st <= max_state:
                raise SequenceError(f"switching state {k}: code {st} outside 0..{max_state} ({self.STATE_FORMAT})")
            if du < 0:
                raise SequenceError(f"switching duration {k}: {du} ns is negative")
            try:
                c_states[k] = st
                c_durations[k] = du
            except TypeError:
                raise SequenceError(f"switching state/duration {k}: integers required, got {st!r}, {du!r}") from None
            total += du
        if total != self.ts_ns:
            raise SequenceError(f"switching durations sum to {total} ns, expected Ts = {self.ts_ns} ns")
        load = self._load_c
        if self._inertia:  # under a dyno the load stays zero (the mechanics setter), no breakpoint splits the period
            t0 = int(self._s.t_ns) / 1e9
            load0, slope = self._load.value_and_slope(t0)
            inside = self._load.breakpoints_between(t0, t0 + total * 1e-9)
            load.value, load.slope, load.n_bp = load0, slope, self._set_load_breakpoints(inside) if inside else 0
        rc = self._kernel_advance(self._p, self._s, c_states, c_durations, n, load, self._trace_dt, self._trace_ptr,
                                  self._trace_cap, self._stats)
        if rc != 0:
            raise PlantFaultError(f"plant kernel rejected the period (code {rc})")
        return tuple.__new__(PeriodStats, _STATS_STRUCT.unpack_from(self._stats_buf))

    def _set_load_breakpoints(self, inside: list[tuple[float, float, float]]) -> int:
        if len(inside) > MAX_LOAD_BREAKPOINTS:
            raise ParameterError(f"load profile has {len(inside)} breakpoints inside one control period "
                                 f"(at most {MAX_LOAD_BREAKPOINTS})")
        for i, (tb, value, slope) in enumerate(inside):
            self._load_bp[3 * i], self._load_bp[3 * i + 1], self._load_bp[3 * i + 2] = tb, value, slope
        return len(inside)

    def kernel_view(self) -> KernelView:
        """Addresses of the kernel structs (valid while this plant lives) and the per-period trace facts."""
        def addr(ptr: Any) -> int:
            return int(self._ffi.cast("uintptr_t", ptr))

        table = 0 if self.KERNEL_TABLE is None else addr(getattr(self.NATIVE_MODULE.lib, self.KERNEL_TABLE)())
        return KernelView(table, addr(self._p), addr(self._s), addr(self._trace_buf), self._trace_cap, self._trace_dt,
                          self._inertia)

    @property
    def state_bytes(self) -> int:
        """Size of the kernel's state struct [bytes] (a native loop's copy of the state: loop.c sample_adc)."""
        return int(self._ffi.sizeof(self._s[0]))

    @property
    def last_trace(self) -> npt.NDArray[np.float64]:
        """High-rate trace rows of the last period: columns TRACE_COLUMNS (view, copy to keep)."""
        return self._trace_np[: int(self._stats.trace_n)]

    def check_trips(self, smp: Any = None) -> str | None:
        """Trip reason ('overcurrent ...' / 'overspeed ...') for a sample (default: now), or None."""
        smp = self.sample() if smp is None else smp
        peak = max(abs(i) for i in smp.phase_currents)
        if peak > self.params.i_trip:
            return f"overcurrent: |i| = {peak:.2f} A > i_trip = {self.params.i_trip:.2f} A"
        rpm = abs(smp.omega_m) * 60.0 / (2.0 * math.pi)
        if rpm > self.params.speed_trip_rpm:
            return f"overspeed: {rpm:.0f} rpm > speed_trip_rpm = {self.params.speed_trip_rpm:.0f} rpm"
        return None

    def sample(self) -> Any:
        """Exact state at the current time (the period start)."""
        raise NotImplementedError


class ThreePhasePlant(PlantBase):
    """A plant on the two-level three-phase inverter: three legs, state codes 4·Sa + 2·Sb + Sc (0..7)."""

    LEGS = 3
    MAX_STATE = 7
    STATE_FORMAT = "4·Sa + 2·Sb + Sc"
