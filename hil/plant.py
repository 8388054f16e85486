"""Python API of the exact PMSM + inverter plant (compiled kernel in hil/native/plant.c)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from pmsm_hil.hil._plant_native import ffi, lib
from pmsm_hil.hil.errors import ParameterError, PlantFaultError, SequenceError
from pmsm_hil.hil.mechanics import DynoMechanics, InertiaMechanics, LoadProfile, Mechanics
from pmsm_hil.hil.motor_params import PmsmParams

MAX_SUBINTERVALS = 8
TRACE_COLUMNS = ("t", "i_a", "i_b", "i_c", "torque", "omega_m")
_SQRT3_2 = math.sqrt(3.0) / 2.0


class PlantSample(NamedTuple):
    """Plant state sampled at a period start (synchronous sampling).

    t [s]; i_a, i_b, i_c, i_d, i_q [A]; theta_e [rad]; omega_m [rad/s]; torque [N·m]; vdc [V].
    """

    t: float
    i_a: float
    i_b: float
    i_c: float
    i_d: float
    i_q: float
    theta_e: float
    omega_m: float
    torque: float
    vdc: float


@dataclass(frozen=True, slots=True)
class PeriodStats:
    """Inverter events of one advanced period (counts of leg gate transitions and pulses)."""

    leg_transitions: int
    boundary_transitions: int
    narrow_pulses: int
    suppressed_pulses: int
    trace_rows: int
    open_phase_events: int = 0
    narrow_pulses_gated: int = 0


class Plant:
    """Exact three-phase PMSM + two-level inverter advanced one control period at a time.

    Each sub-interval's voltage is constant in the stator frame; with the speed constant over a
    sub-interval (dyno mode) the rotor-frame solution is exact (closed form). In inertia mode the
    speed is updated every ``max_piece_s`` from the trapezoidal torque integral.
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
        self._torque_k = 1.5 * params.pole_pairs
        self._psi_f = params.psi_f
        self._dl = params.ld - params.lq
        self._vdc = params.vdc
        self.trace_dt_s = trace_dt_s
        self._p = ffi.new("pl_params_t *")
        self._s = ffi.new("pl_state_t *")
        self._stats = ffi.new("pl_period_stats_t *")
        self._states = ffi.new("int32_t[]", MAX_SUBINTERVALS)
        self._durations = ffi.new("int64_t[]", MAX_SUBINTERVALS)
        rows = 0 if trace_dt_s is None else math.ceil(ts_s / trace_dt_s) + 2
        self._trace_cap = rows
        self._trace_buf = ffi.new("double[]", max(rows, 1) * len(TRACE_COLUMNS))
        self._trace_np: npt.NDArray[np.float64] = np.frombuffer(
            ffi.buffer(self._trace_buf), dtype=np.float64
        ).reshape(-1, len(TRACE_COLUMNS))
        self._trace_dt = 0.0 if trace_dt_s is None else trace_dt_s
        self._trace_ptr = self._trace_buf if trace_dt_s is not None else ffi.NULL
        self._load = LoadProfile.constant(0.0)
        self._set_params(params, max_piece_s)
        self.mechanics = mechanics
        self._s.theta_e = theta0_rad % (2.0 * math.pi)
        if isinstance(mechanics, DynoMechanics):
            self._s.omega_m = mechanics.omega_m
        else:
            self._load = mechanics.load
            self._s.omega_m = mechanics.initial_speed_rpm * 2.0 * math.pi / 60.0
        for leg in range(3):
            self._s.last_edge_t[leg] = -1.0
            self._s.dead_until[leg] = -1.0

    def _set_params(self, params: PmsmParams, max_piece_s: float) -> None:
        p = self._p
        p.rs, p.ld, p.lq, p.psi_f, p.vdc = params.rs, params.ld, params.lq, params.psi_f, params.vdc
        p.j, p.b, p.t_dead, p.t_mpw = params.j, params.b, params.t_dead, params.t_mpw
        p.max_piece = max_piece_s
        p.pole_pairs = params.pole_pairs

    @property
    def mechanics(self) -> Mechanics:
        """Current mechanical mode."""
        return self._mechanics

    @mechanics.setter
    def mechanics(self, mechanics: Mechanics) -> None:
        self._mechanics = mechanics
        if isinstance(mechanics, DynoMechanics):
            self._p.inertia_mode = 0
            self._s.omega_m = mechanics.omega_m
        elif isinstance(mechanics, InertiaMechanics):
            self._p.inertia_mode = 1
            self._load = mechanics.load
        else:
            raise ParameterError(f"unknown mechanics mode {mechanics!r}")

    def set_state(self, *, i_d: float | None = None, i_q: float | None = None,
                  theta_e: float | None = None, omega_m: float | None = None, gate: int | None = None) -> None:
        """Overwrite parts of the state: currents [A], angle [rad], speed [rad/s], applied gate code."""
        if gate is not None:
            if not 0 <= gate <= 7:
                raise SequenceError(f"gate code {gate} outside 0..7")
            self._s.gate = gate
        if i_d is not None:
            self._s.i_d = i_d
        if i_q is not None:
            self._s.i_q = i_q
        if theta_e is not None:
            self._s.theta_e = theta_e % (2.0 * math.pi)
        if omega_m is not None:
            self._s.omega_m = omega_m

    @property
    def time_s(self) -> float:
        """Plant time [s]."""
        return int(self._s.t_ns) / 1e9

    @property
    def gate(self) -> int:
        """Gate code currently applied (4·Sa + 2·Sb + Sc)."""
        return int(self._s.gate)

    def sample(self) -> PlantSample:
        """Exact state at the current time (the period start)."""
        s = self._s
        i_d, i_q, th = s.i_d, s.i_q, s.theta_e
        c, sn = math.cos(th), math.sin(th)
        i_al = i_d * c - i_q * sn
        i_be = i_d * sn + i_q * c
        return PlantSample(int(s.t_ns) / 1e9, i_al, -0.5 * i_al + _SQRT3_2 * i_be, -0.5 * i_al - _SQRT3_2 * i_be,
                           i_d, i_q, th, s.omega_m, self._torque_k * (self._psi_f + self._dl * i_d) * i_q,
                           self._vdc)

    def advance(self, states: Sequence[int], durations_ns: Sequence[int]) -> PeriodStats:
        """Apply one control period's switching sequence: state codes and durations [ns] summing to Ts."""
        n = len(states)
        if n == 0 or n > MAX_SUBINTERVALS or len(durations_ns) != n:
            raise SequenceError(
                f"switching sequence needs 1..{MAX_SUBINTERVALS} states with one duration each, "
                f"got {n} states and {len(durations_ns)} durations"
            )
        total = 0
        for k in range(n):
            st, du = states[k], durations_ns[k]
            if not 0 <= st <= 7:
                raise SequenceError(f"switching state {k}: code {st} outside 0..7 (4·Sa + 2·Sb + Sc)")
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
        return self._advance_unchecked(n)

    def _advance_unchecked(self, n: int) -> PeriodStats:
        t0 = int(self._s.t_ns) / 1e9
        load0, slope = self._load.value_and_slope(t0) if self._p.inertia_mode else (0.0, 0.0)
        st = self._stats
        rc = lib.pl_advance(self._p, self._s, self._states, self._durations, n, load0, slope,
                            self._trace_dt, self._trace_ptr, self._trace_cap, st)
        if rc != 0:
            raise PlantFaultError(f"plant kernel rejected the period (code {rc})")
        return PeriodStats(int(st.leg_transitions), int(st.boundary_transitions), int(st.narrow_pulses),
                           int(st.suppressed_pulses), int(st.trace_n), int(st.open_phase_events),
                           int(st.narrow_pulses_gated))

    @property
    def last_trace(self) -> npt.NDArray[np.float64]:
        """High-rate trace rows of the last period: columns TRACE_COLUMNS (view, copy to keep)."""
        return self._trace_np[: int(self._stats.trace_n)]

    def check_trips(self, smp: PlantSample | None = None) -> str | None:
        """Trip reason ('overcurrent ...' / 'overspeed ...') for a sample (default: now), or None."""
        smp = self.sample() if smp is None else smp
        peak = max(abs(smp.i_a), abs(smp.i_b), abs(smp.i_c))
        if peak > self.params.i_trip:
            return f"overcurrent: |i| = {peak:.2f} A > i_trip = {self.params.i_trip:.2f} A"
        rpm = abs(smp.omega_m) * 60.0 / (2.0 * math.pi)
        if rpm > self.params.speed_trip_rpm:
            return f"overspeed: {rpm:.0f} rpm > speed_trip_rpm = {self.params.speed_trip_rpm:.0f} rpm"
        return None
