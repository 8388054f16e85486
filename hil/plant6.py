"""Python API of the exact dual three-phase PMSM + six-leg inverter plant (kernel hil/native/plant6.c).

Same method names as `pmsm_hil.hil.plant.Plant`; states are 6-bit codes [S_A S_B S_C S_U S_V S_W]
(S_A the most significant bit, e.g. V13 = 0b001101). Phases A, B, C sit at 0°, 120°, 240° and U, V, W
at 30°, 150°, 270°; the x-y currents are in the stationary frame (docs/plant.md, "Dual three-phase").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from pmsm_hil.hil._plant_native import ffi, lib
from pmsm_hil.hil.errors import ParameterError, PlantFaultError, SequenceError
from pmsm_hil.hil.mechanics import DynoMechanics, InertiaMechanics, LoadProfile, Mechanics
from pmsm_hil.hil.motor_params import PmsmParams
from pmsm_hil.hil.plant import MAX_SUBINTERVALS, PeriodStats

#: Trace columns of `Plant6.last_trace`: t [s], six phase currents [A], torque [N·m], omega_m [rad/s],
#: x-y currents [A].
TRACE_COLUMNS6 = ("t", "i_a", "i_b", "i_c", "i_u", "i_v", "i_w", "torque", "omega_m", "i_x", "i_y")
N_LEGS = 6
MAX_STATE6 = 63


class PlantSample6(NamedTuple):
    """Dual three-phase plant state at a period start.

    t [s]; i_a, i_b, i_c (set 1), i_u, i_v, i_w (set 2), i_d, i_q, i_x, i_y [A]; theta_e [rad];
    omega_m [rad/s]; torque [N·m]; vdc [V].
    """

    t: float
    i_a: float
    i_b: float
    i_c: float
    i_u: float
    i_v: float
    i_w: float
    i_d: float
    i_q: float
    i_x: float
    i_y: float
    theta_e: float
    omega_m: float
    torque: float
    vdc: float

    @property
    def phase_currents(self) -> tuple[float, float, float, float, float, float]:
        """(i_a, i_b, i_c, i_u, i_v, i_w) [A]."""
        return (self.i_a, self.i_b, self.i_c, self.i_u, self.i_v, self.i_w)


class Plant6:
    """Exact dual three-phase PMSM (VSD model) + six-leg two-level inverter, one period at a time.

    The dq subspace is solved in closed form with the stator-frame voltage constant per sub-interval
    (as `Plant`); the x-y subspace (R, L_ls, stationary frame) is a first-order exponential. Dead time
    uses the sign rule per leg (diode by the phase-current sign at the edge, held for t_dead); the
    three-phase open-phase model is not implemented for six phases.
    """

    def __init__(
        self,
        params: PmsmParams,
        ts_s: float,
        mechanics: Mechanics,
        *,
        theta0_rad: float = 0.0,
        trace_dt_s: float | None = 2e-6,
        max_piece_s: float = 5e-6,
    ) -> None:
        if not params.lls > 0.0:
            raise ParameterError(f"motor parameter 'lls' must be > 0 H for a six-phase plant, got {params.lls}")
        if not (math.isfinite(ts_s) and 1e-6 <= ts_s <= 1e-2):
            raise ParameterError(f"control period 'ts' must be between 1 µs and 10 ms, got {ts_s} s")
        self.ts_ns = round(ts_s * 1e9)
        if abs(self.ts_ns - ts_s * 1e9) > 1e-3:
            raise ParameterError(f"control period 'ts' must be a whole number of ns, got {ts_s} s")
        if trace_dt_s is not None and not (0 < trace_dt_s <= ts_s):
            raise ParameterError(f"'trace_dt' must be in (0, ts], got {trace_dt_s} s")
        if not math.isfinite(theta0_rad):
            raise ParameterError("'theta0' must be finite")
        self.params = params
        self.ts_s = ts_s
        self.trace_dt_s = trace_dt_s
        self._p = ffi.new("p6_params_t *")
        self._s = ffi.new("p6_state_t *")
        self._stats = ffi.new("p6_period_stats_t *")
        self._states = ffi.new("int32_t[]", MAX_SUBINTERVALS)
        self._durations = ffi.new("int64_t[]", MAX_SUBINTERVALS)
        self._phase = ffi.new("double[]", N_LEGS)
        rows = 0 if trace_dt_s is None else math.ceil(ts_s / trace_dt_s) + 2
        self._trace_cap = rows
        self._trace_buf = ffi.new("double[]", max(rows, 1) * len(TRACE_COLUMNS6))
        self._trace_np: npt.NDArray[np.float64] = np.frombuffer(
            ffi.buffer(self._trace_buf), dtype=np.float64
        ).reshape(-1, len(TRACE_COLUMNS6))
        self._trace_dt = 0.0 if trace_dt_s is None else trace_dt_s
        self._trace_ptr = self._trace_buf if trace_dt_s is not None else ffi.NULL
        self._load = LoadProfile.constant(0.0)
        p = self._p
        p.rs, p.ld, p.lq, p.lls, p.psi_f, p.vdc = params.rs, params.ld, params.lq, params.lls, params.psi_f, params.vdc
        p.j, p.b, p.t_dead, p.t_mpw = params.j, params.b, params.t_dead, params.t_mpw
        p.max_piece = max_piece_s
        p.pole_pairs = params.pole_pairs
        self.mechanics = mechanics
        self._s.theta_e = theta0_rad % (2.0 * math.pi)
        if isinstance(mechanics, InertiaMechanics):
            self._s.omega_m = mechanics.initial_speed_rpm * 2.0 * math.pi / 60.0
        for leg in range(N_LEGS):
            self._s.last_edge_t[leg] = -1.0
            self._s.dead_until[leg] = -1.0

    @property
    def mechanics(self) -> Mechanics:
        """Current mechanical mode."""
        return self._mechanics

    @mechanics.setter
    def mechanics(self, mechanics: Mechanics) -> None:
        if isinstance(mechanics, DynoMechanics):
            self._p.inertia_mode = 0
            self._s.omega_m = mechanics.omega_m
        elif isinstance(mechanics, InertiaMechanics):
            self._p.inertia_mode = 1
            self._load = mechanics.load
        else:
            raise ParameterError(f"unknown mechanics mode {mechanics!r}")
        self._mechanics = mechanics

    def set_state(self, *, i_d: float | None = None, i_q: float | None = None, i_x: float | None = None,
                  i_y: float | None = None, theta_e: float | None = None, omega_m: float | None = None,
                  gate: int | None = None) -> None:
        """Overwrite parts of the state: currents [A], angle [rad], speed [rad/s], applied 6-bit gate code."""
        if gate is not None:
            if not 0 <= gate <= MAX_STATE6:
                raise SequenceError(f"gate code {gate} outside 0..{MAX_STATE6}")
            self._s.gate = gate
        for name, value in (("i_d", i_d), ("i_q", i_q), ("i_x", i_x), ("i_y", i_y), ("omega_m", omega_m)):
            if value is not None:
                setattr(self._s, name, value)
        if theta_e is not None:
            self._s.theta_e = theta_e % (2.0 * math.pi)

    @property
    def time_s(self) -> float:
        """Plant time [s]."""
        return int(self._s.t_ns) / 1e9

    @property
    def gate(self) -> int:
        """Gate code currently applied ([S_A S_B S_C S_U S_V S_W])."""
        return int(self._s.gate)

    def sample(self) -> PlantSample6:
        """Exact state at the current time (the period start)."""
        s = self._s
        ph = self._phase
        lib.p6_phase_currents(s.i_d, s.i_q, s.theta_e, s.i_x, s.i_y, ph)
        return PlantSample6(int(s.t_ns) / 1e9, ph[0], ph[1], ph[2], ph[3], ph[4], ph[5], s.i_d, s.i_q, s.i_x,
                            s.i_y, s.theta_e, s.omega_m, lib.p6_torque(self._p, s.i_d, s.i_q), self._p.vdc)

    def advance(self, states: Sequence[int], durations_ns: Sequence[int]) -> PeriodStats:
        """Apply one period's sequence: 6-bit state codes and durations [ns] summing to Ts.

        `PeriodStats.leg_transitions` counts six legs (divide by 6 legs for the switching frequency)."""
        n = len(states)
        if n == 0 or n > MAX_SUBINTERVALS or len(durations_ns) != n:
            raise SequenceError(
                f"switching sequence needs 1..{MAX_SUBINTERVALS} states with one duration each, "
                f"got {n} states and {len(durations_ns)} durations"
            )
        total = 0
        for k in range(n):
            st, du = states[k], durations_ns[k]
            if not 0 <= st <= MAX_STATE6:
                raise SequenceError(
                    f"switching state {k}: code {st} outside 0..{MAX_STATE6} ([S_A S_B S_C S_U S_V S_W])")
            if du < 0:
                raise SequenceError(f"switching duration {k}: {du} ns is negative")
            try:
                self._states[k] = st
                self._durations[k] = du
            except TypeError:
                raise SequenceError(f"switching state/duration {k}: integers required, got {st!r}, {du!r}") from None
            total += du
        if total != self.ts_ns:
            raise SequenceError(f"switching durations sum to {total} ns, expected Ts = {self.ts_ns} ns")
        t0 = int(self._s.t_ns) / 1e9
        load0, slope = self._load.value_and_slope(t0) if self._p.inertia_mode else (0.0, 0.0)
        st6 = self._stats
        rc = lib.p6_advance(self._p, self._s, self._states, self._durations, n, load0, slope,
                            self._trace_dt, self._trace_ptr, self._trace_cap, st6)
        if rc != 0:
            raise PlantFaultError(f"six-phase plant kernel rejected the period (code {rc})")
        return PeriodStats(int(st6.leg_transitions), int(st6.boundary_transitions), int(st6.narrow_pulses),
                           int(st6.suppressed_pulses), int(st6.trace_n), 0,
                           int(st6.narrow_pulses_gated))

    @property
    def last_trace(self) -> npt.NDArray[np.float64]:
        """Trace rows of the last period: columns TRACE_COLUMNS6 (view, copy to keep)."""
        return self._trace_np[: int(self._stats.trace_n)]

    def check_trips(self, smp: PlantSample6 | None = None) -> str | None:
        """Trip reason ('overcurrent ...' / 'overspeed ...') for a sample (default: now), or None."""
        smp = self.sample() if smp is None else smp
        peak = max(abs(i) for i in smp.phase_currents)
        if peak > self.params.i_trip:
            return f"overcurrent: |i| = {peak:.2f} A > i_trip = {self.params.i_trip:.2f} A"
        rpm = abs(smp.omega_m) * 60.0 / (2.0 * math.pi)
        if rpm > self.params.speed_trip_rpm:
            return f"overspeed: {rpm:.0f} rpm > speed_trip_rpm = {self.params.speed_trip_rpm:.0f} rpm"
        return None
