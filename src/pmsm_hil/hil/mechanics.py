"""Mechanical side of the plant: dyno mode (speed held), inertia mode with a load torque profile, or two masses on
an elastic shaft (the C side: src/pmsm_hil/hil/kernels/mechanics.h, shared by every machine kernel)."""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from pmsm_hil.hil.errors import ParameterError

RPM_TO_RAD_S = 2.0 * math.pi / 60.0


@dataclass(frozen=True, slots=True)
class LoadProfile:
    """Piecewise-linear load torque [N·m] over time [s]: constant, steps and ramps.

    ``points`` are (time [s], torque [N·m]) breakpoints in non-decreasing time; the torque is
    linearly interpolated between them and held after the last. Two points at the same time make
    a step. A single point is a constant load.
    """

    points: tuple[tuple[float, float], ...] = ((0.0, 0.0),)
    _times: tuple[float, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.points:
            raise ParameterError("load profile needs at least one (time, torque) point")
        for idx, (t, tq) in enumerate(self.points):
            if not (math.isfinite(t) and math.isfinite(tq)):
                raise ParameterError(f"load profile point {idx}: time and torque must be finite")
            if idx and t < self.points[idx - 1][0]:
                raise ParameterError(f"load profile point {idx}: time {t} s is before the previous point")
        object.__setattr__(self, "_times", tuple(p[0] for p in self.points))

    @classmethod
    def constant(cls, torque_nm: float) -> LoadProfile:
        """A constant load torque [N·m]."""
        return cls(((0.0, torque_nm),))

    @classmethod
    def steps(cls, initial_nm: float, steps: Sequence[tuple[float, float]]) -> LoadProfile:
        """Load steps: start at ``initial_nm``; at each (time [s], torque [N·m]) jump to the torque."""
        pts: list[tuple[float, float]] = [(0.0, initial_nm)]
        level = initial_nm
        for t, tq in steps:
            pts += [(t, level), (t, tq)]
            level = tq
        return cls(tuple(pts))

    def breakpoints_between(self, t0: float, t1: float) -> list[tuple[float, float, float]]:
        """Breakpoints strictly inside (t0, t1) [s] as (time [s], torque after it [N·m], slope after it [N·m/s])."""
        times = self._times
        lo = bisect.bisect_right(times, t0)
        if lo >= len(times) or times[lo] >= t1:
            return []
        hi = bisect.bisect_left(times, t1)
        return [(t, *self.value_and_slope(t)) for t in sorted(set(times[lo:hi]))]

    def value_and_slope(self, t: float) -> tuple[float, float]:
        """Load torque [N·m] at time t [s] (right-continuous at steps) and its slope [N·m/s]."""
        pts = self.points
        idx = bisect.bisect_right(self._times, t)
        if idx == 0:
            return pts[0][1], 0.0
        if idx >= len(pts):
            return pts[-1][1], 0.0
        (t0, v0), (t1, v1) = pts[idx - 1], pts[idx]
        if t1 == t0:
            return v1, 0.0
        slope = (v1 - v0) / (t1 - t0)
        return v0 + slope * (t - t0), slope


@dataclass(frozen=True, slots=True)
class DynoMechanics:
    """Dyno mode: the load machine holds the shaft at ``speed_rpm`` [rpm] whatever the torque."""

    speed_rpm: float

    @property
    def omega_m(self) -> float:
        """Held mechanical speed [rad/s]."""
        return self.speed_rpm * RPM_TO_RAD_S


@dataclass(frozen=True, slots=True)
class InertiaMechanics:
    """Inertia mode: J·dω/dt = Te − T_load(t) − B·ω, starting at ``initial_speed_rpm`` [rpm]."""

    load: LoadProfile
    initial_speed_rpm: float = 0.0


@dataclass(frozen=True, slots=True)
class TwoMassMechanics:
    """Two masses on an elastic shaft, starting untwisted at ``initial_speed_rpm`` [rpm]:

        J_m·dω/dt   = Te − B·ω − k·Δθ − c·(ω − ω_l)        (the motor mass, B the machine's friction)
        J_l·dω_l/dt = k·Δθ + c·(ω − ω_l) − T_load(t)        dΔθ/dt = ω − ω_l

    ``j_motor``, ``j_load`` [kg·m²] > 0, shaft stiffness ``k_shaft`` [N·m/rad] > 0 and damping ``c_shaft``
    [N·m·s/rad] ≥ 0. The machine's own inertia parameter `j` is not used (the two masses replace it); the torsional
    resonance is at sqrt(k·(J_m + J_l)/(J_m·J_l)) [rad/s]."""

    load: LoadProfile
    j_motor: float
    j_load: float
    k_shaft: float
    c_shaft: float = 0.0
    initial_speed_rpm: float = 0.0

    def __post_init__(self) -> None:
        for name in ("j_motor", "j_load", "k_shaft", "c_shaft", "initial_speed_rpm"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ParameterError(f"two-mass mechanics '{name}' must be a finite number, got {value!r}")
        for name in ("j_motor", "j_load", "k_shaft"):
            if getattr(self, name) <= 0:
                raise ParameterError(f"two-mass mechanics '{name}' must be > 0, got {getattr(self, name)}")
        if self.c_shaft < 0:
            raise ParameterError(f"two-mass mechanics 'c_shaft' must be ≥ 0, got {self.c_shaft}")

    @property
    def resonance_rad_s(self) -> float:
        """Torsional resonance of the undamped shaft sqrt(k·(J_m + J_l)/(J_m·J_l)) [rad/s]."""
        return math.sqrt(self.k_shaft * (self.j_motor + self.j_load) / (self.j_motor * self.j_load))


Mechanics = DynoMechanics | InertiaMechanics | TwoMassMechanics
