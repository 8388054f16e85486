"""Operating range of every controller's defaults, each on its own machine.

Steady scenario (start at the operating point, speed PI closed), firmware and runner defaults (no
--param): over the metrics window the mean speed must be within 1 % of the reference and the mean
electromagnetic torque within max(2 %, 0.05 N·m) of the load torque, at 10/40/70/100 % of rated torque.
A point that a controller cannot hold is listed in EXPECTED_FAILURES with the reason from the docs; the
test then asserts that it really fails (a point that starts to hold fails the test until its entry is
removed) and reports it as XFAIL with the measured miss, so nothing is skipped silently.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import pytest

from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.im_params import ImParams
from pmsm_hil.hil.machine_params import MachineParams
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import Scenario, load_scenario
from pmsm_hil.protocol.ids import ParamId
from pmsm_hil.sim_target.firmware import CONTROLLERS

#: Load points as fractions of the machine's rated torque.
LOAD_FRACTIONS = (0.1, 0.4, 0.7, 1.0)
SPEED_TOL_PCT = 1.0
TORQUE_TOL_REL, TORQUE_TOL_MIN_NM = 0.02, 0.05
#: Within-period trace step [s]: the window means need no 2 µs trace (10 µs changes them by < 1e-4 N·m and
#: 1e-4 %, measured) and the run is ~35 % faster.
TRACE_DT_S = 10e-6


@dataclass(frozen=True, slots=True)
class MachineGrid:
    """A motor preset, its rated torque [N·m], the test speeds [rpm], the controllers made for it, and the
    settling time before and length of the metrics window [s] (the steady scenario starts at the point)."""

    motor: str
    rated_nm: float
    speeds_rpm: tuple[float, ...]
    controllers: tuple[str, ...]
    settle_s: float
    window_s: float
    #: test-id prefix when the controllers also run on another grid's machine
    tag: str = ""


#: Field-weakening grids: the reference FOCs at rated speed, at the base speed and at 1.5× it
#: (`base_speed_rpm`: the corner of the rated torque at the firmware's voltage limit 0.95·Vdc/√3, rounded up).
GRIDS = (
    MachineGrid("niu2020-ipmsm", 7.0, (300.0, 1500.0), ("mpcc", "dsvm-20", "fcs-mpc-1", "fcs-mpc-2", "dbcc-mpc"),
                0.05, 0.1),
    # foc with MTPA and field weakening: base speed 1943 rpm, 1.5× = 2915 rpm (< the 3000 rpm trip)
    MachineGrid("niu2020-ipmsm", 7.0, (300.0, 1500.0, 1943.0, 2915.0), ("foc",), 0.05, 0.1),
    MachineGrid("xiao2023-spmsm", 6.0, (500.0, 2000.0), ("3vmpc", "hv-mpfc"), 0.05, 0.1),
    # the SPMSM with foc (MTPA is id = 0 there): base speed 2148 rpm, 1.5× = 3223 rpm
    MachineGrid("xiao2023-spmsm", 6.0, (500.0, 2000.0, 2148.0, 3223.0), ("foc",), 0.05, 0.1, tag="xiao-"),
    # 750-3000 rpm, 8-80 N·m: inside the voltage (126 V back-EMF at 3000 rpm < 173 V linear reach) and current
    # (66.7 A rated < 300 A trip) limits of the preset. J = 0.1 kg·m² (77x niu2020): the window mean of the
    # torque follows the residual speed drift J·Δω/T, hence the longer window
    MachineGrid("zhang2021-dtpmsm", 80.0, (750.0, 1500.0, 3000.0), ("mptc1", "mptc2", "mptc3"), 0.2, 0.2),
    # mptc1..3 with field weakening (the flux reference capped by the voltage limit): base speed 3800 rpm, 1.5× =
    # 5700 rpm (< the 6000 rpm trip); the speed drift at 10 % load needs the longer settling (0.2 s left the mean
    # torque 0.18 N·m off at 5700 rpm)
    MachineGrid("zhang2021-dtpmsm", 80.0, (3800.0, 5700.0), ("mptc1", "mptc2", "mptc3"), 0.4, 0.2, tag="fw-"),
    # the saturated flux-map machine (kind pmsm-fluxmap, docs/plant.md): the controllers see the linear model fitted
    # at the rated point (Ld 10.2 mH, Lq 13.3 mH, ψf 0.2055 Wb), the plant the saturating map
    MachineGrid("niu2020-ipmsm-sat", 7.0, (300.0, 1500.0), ("mpcc",), 0.05, 0.1, tag="sat-"),
    # foc on it up to 1.5× the base speed of that linear model: 1997 rpm, 1.5× = 2996 rpm (< the 3600 rpm trip)
    MachineGrid("niu2020-ipmsm-sat", 7.0, (300.0, 1500.0, 1997.0, 2996.0), ("foc",), 0.05, 0.1, tag="sat-"),
    # the induction machine starts at zero flux: im-foc's flux loop (20 ms) and the speed PI settle within 0.2 s
    # below base speed (1277 rpm at the 0.9 Wb rotor flux); above it (the rated 1439 rpm, 1.5× base = 1916 rpm) the
    # flux reference follows the voltage-limit loop (15 rad/s crossover), hence the longer settling
    MachineGrid("im-2k2", 14.6, (500.0, 1000.0), ("im-foc",), 0.2, 0.2, tag="im-"),
    MachineGrid("im-2k2", 14.6, (1277.0, 1439.0, 1916.0), ("im-foc",), 0.3, 0.2, tag="im-"),
)

# mptc1 neither predicts nor costs the x-y subspace: every G1 vector puts 52 V on L_ls = 80 µH and the x-y
# current integrates past the 300 A protection within milliseconds (physics of the preset's machine).
_MPTC1 = "physics: x-y current runaway (docs/comparisons/zhang2021.md, 'mptc1: the x-y subspace is an integrator')"
# mptc3 as specified: one V3 period moves the torque by ~26 N·m against the 4 N·m band and its torque-only cost
# J2 lets i_d drift; measured with the machine's speed PI (preset: kp 3, ki 5): at 3000 rpm its mean torque bias
# leaves the speed 1.1-1.4 % low at 10-40 % load, and the i_d excursions reach the 300 A protection at 750 rpm /
# 40 % and 3000 rpm / 70-100 % (loss of flux control at rated speed).
_MPTC3 = ("mptc3 as specified: torque step per period >> band, i_d drift (docs/comparisons/zhang2021.md, 'mptc3: "
          "torque-only cost J2 lets i_d drift'), bias turned into droop")
_MPTC3_TRIP = ("mptc3 loses flux control (i_d drift reaches the protection), trips (docs/comparisons/zhang2021.md, "
               "summary (iii))")

#: (controller, speed [rpm] or None for all, load fraction or None for all) -> (expected miss, reason).
#: Expected miss: "trip" (the protection ends the run) or "tracking" (speed or torque out of tolerance).
EXPECTED_FAILURES: dict[tuple[str, float | None, float | None], tuple[str, str]] = {
    ("mptc1", None, None): ("trip", _MPTC1),
    ("mptc3", 750.0, 0.4): ("trip", _MPTC3_TRIP),
    **{("mptc3", 3000.0, f): ("tracking", _MPTC3) for f in (0.1, 0.4)},
    **{("mptc3", 3000.0, f): ("trip", _MPTC3_TRIP) for f in (0.7, 1.0)},
    # above base speed (field weakening) mptc3 keeps both of its misses: its torque-only cost J2 cannot hold the
    # weakened flux either (measured: 10 % load 5-7 % slow, 40-100 % at 3800 rpm and 100 % at 5700 rpm trip, the
    # rest 25-55 % slow); mptc2, the same references with the full cost, holds all eight points
    **{("mptc3", n, 0.1): ("tracking", _MPTC3) for n in (3800.0, 5700.0)},
    **{("mptc3", 3800.0, f): ("trip", _MPTC3_TRIP) for f in (0.4, 0.7, 1.0)},
    **{("mptc3", 5700.0, f): ("tracking", _MPTC3) for f in (0.4, 0.7)},
    ("mptc3", 5700.0, 1.0): ("trip", _MPTC3_TRIP),
}


@dataclass(frozen=True, slots=True)
class Point:
    """One grid point: machine, controller, speed [rpm] and load as a fraction of rated torque."""

    grid: MachineGrid
    controller: str
    speed_rpm: float
    load_frac: float

    @property
    def load_nm(self) -> float:
        """Load torque [N·m]."""
        return self.grid.rated_nm * self.load_frac

    @property
    def name(self) -> str:
        """Test id, e.g. mpcc-300rpm-40%."""
        return f"{self.grid.tag}{self.controller}-{self.speed_rpm:.0f}rpm-{100 * self.load_frac:.0f}%"


POINTS = [Point(g, c, n, f)
          for g in GRIDS for c in g.controllers for n in g.speeds_rpm for f in LOAD_FRACTIONS]


def expected_failure(p: Point) -> tuple[str, str] | None:
    """The EXPECTED_FAILURES entry covering point p, if any."""
    for (ctrl, speed, frac), entry in EXPECTED_FAILURES.items():
        if ctrl == p.controller and speed in (None, p.speed_rpm) and frac in (None, p.load_frac):
            return entry
    return None


@functools.cache
def _motor(name: str) -> MachineParams:
    """The bundled preset, parsed once per worker (frozen; its TOML parse was ~15 % of a grid point's CPU)."""
    return load_motor(name)


@functools.cache
def _steady() -> Scenario:
    """The steady scenario as bundled, parsed once (frozen; each point takes `with_overrides` of it)."""
    return load_scenario("steady")


def miss(p: Point, params: dict[str, float] | None = None) -> tuple[str, str] | None:
    """Run point p with the defaults (plus `params`, controller parameters); None if it holds, else
    (kind, figures) with kind "trip" or "tracking"."""
    sc = _steady().with_overrides(speed_rpm=p.speed_rpm, load_nm=p.load_nm, settle_s=p.grid.settle_s,
                                  duration_s=p.grid.window_s)
    cfg = RunConfig(motor=_motor(p.grid.motor), scenario=sc, controller=p.controller,
                    controller_params=params or {}, trace_dt_s=TRACE_DT_S)
    try:
        m = run_closed_loop(cfg).metrics
    except HilError as exc:  # the protection ended the run before the metrics window
        return "trip", str(exc)
    if m["end_code"] != 0 and m["speed_mean_rpm"] is None:  # ended before the metrics window
        return "trip", m["end_reason"]
    speed_pct = 100.0 * (m["speed_mean_rpm"] - p.speed_rpm) / p.speed_rpm
    torque_err = m["torque_mean_nm"] - p.load_nm
    torque_tol = max(TORQUE_TOL_REL * p.load_nm, TORQUE_TOL_MIN_NM)
    figures = (f"speed {speed_pct:+.3f} % (tol {SPEED_TOL_PCT} %), torque {torque_err:+.3f} N·m "
               f"(tol {torque_tol:.3f}), ripple {m['torque_ripple_rms_nm']:.3f} N·m RMS")
    print(f"{p.name}: {figures}, {m['end_reason']}")
    if m["end_reason"] != "completed":
        return "trip", f"{m['end_reason']}; {figures}"
    if abs(speed_pct) > SPEED_TOL_PCT or abs(torque_err) > torque_tol:
        return "tracking", figures
    return None


@pytest.mark.slow
@pytest.mark.parametrize("p", POINTS, ids=[p.name for p in POINTS])
def test_defaults_hold_speed_and_torque(p: Point) -> None:
    expected = expected_failure(p)
    got = miss(p)
    if expected is None:
        assert got is None, f"{p.name} on {p.grid.motor}: {got}"
        return
    kind, reason = expected
    assert got is not None, f"{p.name} now holds: remove its EXPECTED_FAILURES entry ({reason})"
    assert got[0] == kind, f"{p.name}: expected a {kind} miss, got {got}"
    pytest.xfail(f"{p.name}: {reason}; measured: {got[1]}")


def test_the_machine_speed_pi_comes_from_the_preset() -> None:
    """The speed PI is a drive setting of the machine (its inertia): zhang2021 (J = 0.1 kg·m²) states its own
    gains, the others keep the niu2020 paper's, and the runner writes them."""
    from pmsm_hil.protocol.ids import ParamId

    sc = load_scenario("steady")
    zhang = RunConfig(motor=load_motor("zhang2021-dtpmsm"), scenario=sc, controller="mptc2").target_parameters()
    niu = RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc).target_parameters()
    assert (zhang[ParamId.SPEED_KP], zhang[ParamId.SPEED_KI]) == (3.0, 5.0)
    assert (niu[ParamId.SPEED_KP], niu[ParamId.SPEED_KI]) == (0.8, 0.35)


#: the firmware's field-weakening voltage limit: this share of the linear SVPWM reach Vdc/√3 (FOC_FW_MARGIN,
#: IM_FOC_FW_MARGIN in firmware_stub/src/foc.c, im_foc.c)
FW_MARGIN = 0.95
#: the controllers with field weakening, and the grids that test them above base speed
FW_CONTROLLERS = ("foc", "im-foc", "mptc1", "mptc2", "mptc3")


def _torque_factor(motor: object) -> float:
    """T = factor·p·(ψd·iq − ψq·id): 1.5 for a three-phase machine, 3 for the dual three-phase one (amplitude
    invariant VSD, docs/algorithms/mptc.md)."""
    return 3.0 if getattr(motor, "is_six_phase", False) else 1.5


def _bisect(f: Callable[[float], float], lo: float, hi: float) -> float:
    """The x in [lo, hi] where the increasing f(x) crosses 0 (60 halvings)."""
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) < 0 else (lo, mid)
    return 0.5 * (lo + hi)


def _pm_voltage(m: dict[ParamId, float], w_e: float, i_d: float, i_q: float) -> float:
    """Steady-state |v| [V] of the linear PMSM model m at electrical speed w_e [rad/s] and currents [A]."""
    rs, ld, lq, psi = m[ParamId.RS], m[ParamId.LD], m[ParamId.LQ], m[ParamId.PSI_F]
    return math.hypot(rs * i_d - w_e * lq * i_q, rs * i_q + w_e * (ld * i_d + psi))


def _im_voltage(im: ImParams, w_e: float, psi: float, i_q: float) -> float:
    """Steady-state |u| [V] of the inverse-Γ induction machine in the rotor-flux frame at rotor flux psi [Wb]."""
    i_d, w_s = psi / im.lm, w_e + im.rr * i_q / psi
    return math.hypot(im.rs * i_d - w_s * im.lsigma * i_q, im.rs * i_q + w_s * (im.lsigma * i_d + psi))


def _mtpa(m: dict[ParamId, float], torque: float, pole_pairs: int, factor: float = 1.5) -> tuple[float, float]:
    """MTPA (id, iq) [A] of the linear PMSM model at torque [N·m], by fixed point as the firmware's (`factor`:
    `_torque_factor`)."""
    dl, psi_f, i_d, i_q = m[ParamId.LQ] - m[ParamId.LD], m[ParamId.PSI_F], 0.0, 0.0
    for _ in range(20):
        i_q = torque / (factor * pole_pairs * (psi_f - dl * i_d))
        i_d = -dl * i_q * i_q / (0.5 * psi_f + math.sqrt(0.25 * psi_f ** 2 + dl * dl * i_q * i_q)) if dl > 0 else 0.0
    return i_d, i_q


def base_speed_rpm(motor_name: str) -> float:
    """Base speed [rpm]: the highest speed at which the rated torque needs no field weakening — the PMSM's MTPA
    currents, the induction machine's nominal flux psi_r_ref — at the firmware's voltage limit 0.95·Vdc/√3, in the
    steady state of the model the controller is told."""
    motor = load_motor(motor_name)
    vlim, p, rated = FW_MARGIN * motor.vdc / math.sqrt(3.0), motor.pole_pairs, motor.torque_rating_nm
    if isinstance(motor, ImParams):
        psi = motor.psi_r_ref
        i_q = rated / (1.5 * p * psi)
        w_e = _bisect(lambda w: _im_voltage(motor, w, psi, i_q) - vlim, 0.0, 1e4)
    else:
        m = motor.model_parameters()
        i_d, i_q = _mtpa(m, rated, p, _torque_factor(motor))
        w_e = _bisect(lambda w: _pm_voltage(m, w, i_d, i_q) - vlim, 0.0, 1e5)
    return w_e / p * 30.0 / math.pi


def max_torque_nm(motor_name: str, speed_rpm: float) -> float:
    """The torque the current limit (0.8·i_trip, what the runner tells the firmware) and the voltage limit allow
    at speed_rpm [N·m], steady state of the controller's model: the best over 200 d currents (PMSM, down to
    −ψf/Ld) or rotor fluxes (induction machine, down to a quarter of psi_r_ref)."""
    motor = load_motor(motor_name)
    vlim, p, imax = FW_MARGIN * motor.vdc / math.sqrt(3.0), motor.pole_pairs, 0.8 * motor.i_trip
    w_e = speed_rpm * math.pi / 30.0 * p
    # the controller's linear model, fitted once (the flux-map machine's fit costs ~10 ms: 200 fits were 2 CPU-s)
    m = None if isinstance(motor, ImParams) else motor.model_parameters()
    best = 0.0
    for k in range(1, 201):
        if isinstance(motor, ImParams):
            psi = motor.psi_r_ref * (0.25 + 0.75 * k / 200)
            i_d, flux = psi / motor.lm, psi

            def volt(iq: float, psi: float = psi, im: ImParams = motor) -> float:
                return _im_voltage(im, w_e, psi, iq)
        else:
            assert m is not None
            i_d = -min(imax, m[ParamId.PSI_F] / m[ParamId.LD]) * k / 200
            flux = m[ParamId.PSI_F] + (m[ParamId.LD] - m[ParamId.LQ]) * i_d

            def volt(iq: float, i_d: float = i_d, m: dict[ParamId, float] = m) -> float:
                return _pm_voltage(m, w_e, i_d, iq)
        if abs(i_d) >= imax or volt(0.0) > vlim:
            continue
        i_q_max = math.sqrt(imax * imax - i_d * i_d)
        i_q = i_q_max if volt(i_q_max) <= vlim else _bisect(lambda iq, f=volt: f(iq) - vlim, 0.0, i_q_max)
        best = max(best, _torque_factor(motor) * p * flux * i_q)
    return best


FW_GRIDS = [g for g in GRIDS if set(g.controllers) <= set(FW_CONTROLLERS)]


@pytest.mark.parametrize("grid", FW_GRIDS, ids=lambda g: f"{g.motor}-{'-'.join(g.controllers)}-{g.speeds_rpm[-1]:.0f}")
def test_the_field_weakening_grids_reach_rated_and_1_5x_base_speed(grid: MachineGrid) -> None:
    """Every preset a reference FOC drives is tested at its rated speed and at 1.5× its base speed, where the
    voltage and current limits still allow the rated torque (so 100 % load is inside the drive's range)."""
    motor = load_motor(grid.motor)
    if grid.speeds_rpm[-1] < base_speed_rpm(grid.motor):
        return  # a below-base grid of the same machine (the one above base covers it)
    top = grid.speeds_rpm[-1]
    assert top >= 1.5 * base_speed_rpm(grid.motor), (top, base_speed_rpm(grid.motor))
    assert any(n >= motor.rated_speed_rpm for g in FW_GRIDS if g.motor == grid.motor for n in g.speeds_rpm)
    assert max_torque_nm(grid.motor, top) >= grid.rated_nm
    assert top < motor.speed_trip_rpm


def test_every_controller_is_in_the_grid() -> None:
    """Every controller the reference firmware implements (phases 0 is `off`) has its grid."""
    assert {p.controller for p in POINTS} == {c.name for c in CONTROLLERS if c.implemented and c.phases}
