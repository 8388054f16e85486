"""Parameters of a saturated PMSM given by a flux map (kind "pmsm-fluxmap"): the map file and the drive facts.

A motor TOML of this kind names the map beside `kind` (`flux_map = "map.csv"`, relative to the TOML) and gives rs,
pole_pairs, vdc, j (b, t_mpw, trips, rated figures, speed PI optional) in `[parameters]`. The map is read and
checked when the parameters are made (src/pmsm_hil/hil/fluxmap.py): monotone, non-singular, and reaching the trip
current.

What the controllers are told (`model_parameters`): the linear model ψd = Ld·id + ψf, ψq = Lq·iq fitted at the
rated operating point on the q axis, (0, iq_r) with 1.5·p·ψd(0, iq_r)·iq_r = the rated torque: ψf = ψd(0, iq_r),
Lq = ψq(0, iq_r)/iq_r (secant: the model's flux, hence its back-EMF ω·ψ and its torque, are exact at rated load),
Ld = ∂ψd/∂id there (incremental: at id = 0 a secant has no meaning). Docs: docs/plant.md "Saturated PMSM".

Units: SI (Ω, V, kg·m², N·m·s/rad, s, A, Wb, H); speeds in rpm where named so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, ClassVar

from pmsm_hil.hil.drive_params import DriveParams, WithDrive
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.fluxmap import Interpolant, MapChecks, load_interpolant
from pmsm_hil.hil.machine_params import check_preset_keys
from pmsm_hil.protocol.ids import ParamId

KIND = "pmsm-fluxmap"

_SETTABLE: dict[str, str] = {"rs": "Ω", "pole_pairs": "", "vdc": "V", "j": "kg·m²", "b": "N·m·s/rad", "t_dead": "s",
                             "t_mpw": "s",
                             "i_trip": "A", "speed_trip_rpm": "rpm", "rated_speed_rpm": "rpm",
                             "rated_torque_nm": "N·m", "speed_kp": "N·m/(rad/s)", "speed_ki": "N·m/rad"}


@dataclass(frozen=True, slots=True)
class FluxMapParams(WithDrive):
    """A saturated PMSM: `flux_map` the map file's path (CSV or SyR-e .mat), rs [Ω], pole pairs, and the drive every
    kind has (`drive`: DriveParams, its fields also read as attributes: `params.j`). Build one from flat values with
    `FluxMapParams.build(flux_map=..., rs=..., pole_pairs=..., vdc=..., j=...)`."""

    flux_map: str
    rs: float
    pole_pairs: int
    drive: DriveParams
    name: str = "fluxmap"

    SETTABLE_UNITS: ClassVar[dict[str, str]] = _SETTABLE
    #: top-level keys of a motor TOML that name files next to it (src/pmsm_hil/hil/presets_loader.py)
    FILE_KEYS: ClassVar[tuple[str, ...]] = ("flux_map",)
    REQUIRED: ClassVar[tuple[str, ...]] = ("flux_map", "rs", "pole_pairs", "vdc", "j")

    @classmethod
    def from_values(cls, values: dict[str, Any], name: str) -> FluxMapParams:
        """From a preset's values (`flux_map` resolved by the loader); ParameterError naming a bad key."""
        check_preset_keys(values, cls.parameter_names(), cls.REQUIRED, "pmsm-fluxmap ")
        return cls.build(name=name, **{k: _clean(k, v) for k, v in values.items()})

    def __post_init__(self) -> None:
        if isinstance(self.rs, bool) or not isinstance(self.rs, int | float) or not math.isfinite(self.rs):
            raise ParameterError(f"motor parameter 'rs' must be a finite number, got {self.rs!r}")
        if self.rs <= 0:
            raise ParameterError(f"motor parameter 'rs' must be > 0, got {self.rs}")
        if isinstance(self.pole_pairs, bool) or not isinstance(self.pole_pairs, int) or self.pole_pairs < 1:
            raise ParameterError(f"motor parameter 'pole_pairs' must be an integer ≥ 1, got {self.pole_pairs!r}")
        checks = self.checks
        if not checks.covers(self.i_trip):
            raise ParameterError(
                f"flux_map {self.flux_map}: the grid (id {checks.id_range_a[0]:g}..{checks.id_range_a[1]:g} A, "
                f"iq {checks.iq_range_a[0]:g}..{checks.iq_range_a[1]:g} A) does not reach i_trip = {self.i_trip:g} A "
                "in −id and ±iq: extend the map or lower i_trip")

    @property
    def interpolant(self) -> Interpolant:
        """The map's interpolant (cached per file)."""
        return load_interpolant(self.flux_map)[0]

    @property
    def checks(self) -> MapChecks:
        """The map's load checks (cached per file)."""
        return load_interpolant(self.flux_map)[1]

    def torque_nm(self, i_d: float, i_q: float) -> float:
        """Electromagnetic torque 1.5·p·(ψd·iq − ψq·id) [N·m] at currents [A]."""
        return _torque_nm(self.interpolant, self.pole_pairs, i_d, i_q)

    @property
    def torque_rating_nm(self) -> float:
        """Rated torque [N·m]: the preset's, else the torque at id = 0, iq = i_trip/2."""
        return self.rated_torque_nm if self.rated_torque_nm > 0 else self.torque_nm(0.0, 0.5 * self.i_trip)

    def operating_point(self) -> float:
        """iq_r [A]: the q current at id = 0 giving the rated torque (bisection on the map, 60 halvings)."""
        target, hi = self.torque_rating_nm, self.checks.iq_range_a[1]
        iq_r = _operating_point(self.interpolant, self.pole_pairs, target, hi)
        if iq_r is None:
            raise ParameterError(f"flux_map {self.flux_map}: the map's torque at id = 0 stays below the rated "
                                 f"{target:g} N·m up to iq = {hi:g} A")
        return iq_r

    def linear_model(self) -> tuple[float, float, float]:
        """(Ld [H], Lq [H], ψf [Wb]) the controllers are told (module docstring)."""
        iq_r = self.operating_point()
        psi_d, psi_q, jac = self.interpolant.flux(0.0, iq_r)
        return float(jac[0, 0]), psi_q / iq_r, psi_d

    def model_parameters(self) -> dict[ParamId, float]:
        """Rs, Ld, Lq, ψf of the linear model fitted at the rated point (module docstring)."""
        ld, lq, psi_f = self.linear_model()
        return {ParamId.RS: self.rs, ParamId.LD: ld, ParamId.LQ: lq, ParamId.PSI_F: psi_f}

    def with_overrides(self, overrides: dict[str, Any]) -> FluxMapParams:
        """A copy with `--set` overrides (the map file is not settable)."""
        unknown = set(overrides) - set(_SETTABLE)
        if unknown:
            raise ParameterError(f"unknown motor parameter(s) {', '.join(sorted(unknown))} for a pmsm-fluxmap "
                                 f"machine (known: {', '.join(sorted(_SETTABLE))})")
        return self.with_values(**{k: _clean(k, v) for k, v in overrides.items()})


def _torque_nm(interp: Interpolant, pole_pairs: int, i_d: float, i_q: float) -> float:
    """1.5·p·(ψd·iq − ψq·id) [N·m] on the map's interpolant at currents [A]."""
    psi_d, psi_q, _ = interp.flux(i_d, i_q)
    return 1.5 * pole_pairs * (psi_d * i_q - psi_q * i_d)


@lru_cache(maxsize=16)
def _operating_point(interp: Interpolant, pole_pairs: int, target: float, hi: float) -> float | None:
    """The bisection of `FluxMapParams.operating_point` on one interpolant (a map's, cached per file: the key is
    that object), None when the torque at iq = hi stays below target [N·m]. Cached: every run asks for the model
    twice (the checks, the ConfigParams), and each fit is 62 interpolations (it was also 62 reads of the file's
    path and status through `load_interpolant`, ~10 ms of CPU a fit)."""
    if _torque_nm(interp, pole_pairs, 0.0, hi) < target:
        return None
    lo = 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _torque_nm(interp, pole_pairs, 0.0, mid) < target else (lo, mid)
    return 0.5 * (lo + hi)


def _clean(key: str, value: Any) -> Any:
    if key == "flux_map":
        if not isinstance(value, str):
            raise ParameterError(f"'flux_map' must be a file name, got {value!r}")
        return value
    if key == "pole_pairs":
        if isinstance(value, bool) or float(value) != int(value):
            raise ParameterError(f"'pole_pairs' must be an integer, got {value!r}")
        return int(value)
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"motor parameter '{key}' must be a number, got {value!r}") from None


__all__ = ["KIND", "FluxMapParams"]
