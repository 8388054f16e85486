"""Saturated PMSM from a flux map (kind "pmsm-fluxmap"): the map's interpolant and checks, its
loaders (CSV, SyR-e .mat), the linear map replaying niu2020 through `hil plant replay`, and the kernel's
integration against scipy's solve_ivp on the shipped saturated map."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.fluxmap import FluxMap, check_map, interpolant, load_interpolant, write_csv_map
from pmsm_hil.hil.fluxmap_model import SaturationModel, preset_csv_path
from pmsm_hil.hil.fluxmap_params import FluxMapParams
from pmsm_hil.hil.fluxmap_plant import FluxMapPlant
from pmsm_hil.hil.machine import machine_for
from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.presets_loader import load_motor

LD, LQ, PSI_F = 0.012, 0.014, 0.21  # niu2020-ipmsm
GRID = np.linspace(-36.0, 36.0, 25)
TOML = ('name = "niu-linear-map"\nkind = "pmsm-fluxmap"\nflux_map = "{csv}"\n[parameters]\nrs = 4.5\n'
        "pole_pairs = 3\nvdc = 311.0\nj = 0.0013\ni_trip = 30.0\nrated_torque_nm = 7.0\n")


def _linear_map(grid_q: np.ndarray = GRID) -> FluxMap:
    i_d, i_q = np.meshgrid(GRID, grid_q, indexing="ij")
    return FluxMap(GRID, grid_q, LD * i_d + PSI_F, LQ * i_q, "linear")


@pytest.fixture()
def linear_toml(tmp_path: Path) -> Path:
    write_csv_map(_linear_map(), tmp_path / "lin.csv")
    path = tmp_path / "lin.toml"
    path.write_text(TOML.format(csv="lin.csv"), encoding="utf-8")
    return path


def _random_sequence(path: Path, periods: int, seed: int) -> None:
    """A replay input in the sequence form: 1-3 random states per 100 µs period, random durations (ns)."""
    rng = np.random.default_rng(seed)
    with path.open("w", newline="", encoding="utf-8") as out:
        w = csv.writer(out)
        w.writerow(["s0", "t0", "s1", "t1", "s2", "t2"])
        for _ in range(periods):
            n = int(rng.integers(1, 4))
            cuts = sorted(int(c) for c in rng.integers(1, 100_000, n - 1))
            durs = np.diff([0, *cuts, 100_000])
            row: list[str] = []
            for k in range(3):
                row += [str(int(rng.integers(0, 8))), f"{durs[k] * 1e-9:.9f}"] if k < n else ["", ""]
            w.writerow(row)


def _read(path: Path) -> np.ndarray:
    with path.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    return np.array([[float(v) for v in row] for row in rows[1:]])


def test_the_interpolant_reproduces_a_linear_map_and_matches_the_kernel() -> None:
    """PCHIP slopes + bicubic Hermite reproduce an affine map to rounding; the C kernel's fm_flux and its Newton
    inverse agree with the numpy interpolant; beyond the grid both continue to first order."""
    interp = interpolant(_linear_map())
    for i_d, i_q in ((1.3, 2.7), (-20.1, 13.3), (35.9, -35.9), (40.0, 5.0)):
        psi_d, psi_q, jac = interp.flux(i_d, i_q)
        assert psi_d == pytest.approx(LD * i_d + PSI_F, abs=1e-15)
        assert psi_q == pytest.approx(LQ * i_q, abs=1e-15)
        assert np.allclose(jac, [[LD, 0.0], [0.0, LQ]], atol=1e-15)
    sat = load_motor("niu2020-ipmsm-sat")
    assert isinstance(sat, FluxMapParams)
    p = FluxMapPlant(sat, 1e-4, DynoMechanics(0.0), trace_dt_s=None)
    from pmsm_hil.hil._plant_native import ffi, lib

    out = ffi.new("double[6]")
    for i_d, i_q in ((0.0, 7.4), (-25.0, 20.0), (12.0, -30.0), (38.0, 3.0)):
        lib.fm_flux(p._p, i_d, i_q, out, out + 1, ffi.NULL)
        psi_d, psi_q, _ = sat.interpolant.flux(i_d, i_q)
        assert (out[0], out[1]) == pytest.approx((psi_d, psi_q), abs=1e-15)
        out[2], out[3] = 0.0, 0.0
        assert lib.fm_currents(p._p, psi_d, psi_q, out + 2, out + 3) == 0
        assert (out[2], out[3]) == pytest.approx((i_d, i_q), abs=1e-10)


def test_the_shipped_map_is_its_generator_and_reciprocal_to_its_discretisation() -> None:
    """The preset CSV equals the saturation model's map (src/pmsm_hil/hil/fluxmap_model.py) to 1e-15 Wb; the model is
    reciprocal by construction, so the residual left is the node-slope estimate's (< 2 % of the inductances);
    a linear map's is 0."""
    fmap = SaturationModel().flux_map()
    interp, checks = load_interpolant(str(preset_csv_path()))
    assert np.abs(interp.fmap.psi_d - fmap.psi_d).max() < 1e-15
    assert np.abs(interp.fmap.psi_q - fmap.psi_q).max() < 1e-15
    assert 0.0 < checks.reciprocity_rel < 0.02
    assert check_map(interpolant(_linear_map())).reciprocity_max_h == 0.0
    # saturation is in the map: the apparent q inductance at 30 A is well below the unsaturated 16 mH
    psi_q30 = interp.flux(0.0, 30.0)[1]
    assert psi_q30 / 30.0 < 0.6 * 0.016


@pytest.mark.parametrize(("rpm", "sets"), [("1500", []), ("300", ["--set", "t_dead=2e-6", "--set", "t_mpw=1e-6"])],
                         ids=["ideal-switches", "dead-time"])
def test_the_linear_map_replays_niu2020(linear_toml: Path, tmp_path: Path, rpm: str, sets: list[str]) -> None:
    """Done-when: `hil plant replay` of the linear niu2020 map and of `--motor niu2020-ipmsm` with the same 2000
    random periods agree to ≤ 1e-6 A (measured: 3.3e-11 A with ideal switches; 1.6e-9 A with 2 µs dead time,
    where diode conduction and open phases come in)."""
    seq = tmp_path / "seq.csv"
    _random_sequence(seq, 2000, seed=28)
    outs = []
    for motor in (str(linear_toml), "niu2020-ipmsm"):
        out = tmp_path / f"out-{len(outs)}.csv"
        assert main(["plant", "replay", "--motor", motor, "--rpm", rpm, "--ts", "1e-4", "--input", str(seq),
                     "--output", str(out), *sets]) == 0
        outs.append(_read(out))
    fm, pm = outs
    assert fm.shape == pm.shape == (2001, 9)
    currents = slice(1, 6)  # i_a, i_b, i_c, i_d, i_q
    err = np.abs(fm[:, currents] - pm[:, currents]).max()
    print(f"linear map vs niu2020 ({rpm} rpm {' '.join(sets)}): max |Δi| = {err:.3g} A over 2000 periods")
    assert err <= 1e-6
    assert np.abs(fm[:, 6] - pm[:, 6]).max() < 1e-6 * 1.5 * 3 * 0.3  # torque
    assert np.abs(fm[:, 1:6]).max() > 2.0  # the sequence drove real currents


def test_dead_time_diode_blocking_and_open_phase_as_the_pmsm_kernel(linear_toml: Path) -> None:
    """With dead time the flux-map kernel's diode conduction, blocking and open phase (terminal potential solved in
    the right-hand side) follow the PMSM kernel's (closed form, bisection, RK4 loop current) on the linear map: the
    same open-phase events and trace rows within 1e-6 A over 1000 random periods at 300 rpm with 5 µs dead time."""
    sets = {"t_dead": 5e-6, "t_mpw": 1e-6}
    plants = [machine_for(load_motor(name, sets)).build_plant(1e-4, DynoMechanics(300.0), trace_dt_s=2e-6)
              for name in (str(linear_toml), "niu2020-ipmsm")]
    rng = np.random.default_rng(5)
    opens = [0, 0]
    worst = 0.0
    for _ in range(1000):
        n = int(rng.integers(1, 4))
        durs = [int(d) for d in np.diff([0, *sorted(int(c) for c in rng.integers(0, 100_000, n - 1)), 100_000])]
        states = [int(x) for x in rng.integers(0, 8, n)]
        for k, plant in enumerate(plants):
            opens[k] += plant.advance(states, durs).open_phase_events
        traces = [p.last_trace for p in plants]
        assert traces[0].shape == traces[1].shape
        worst = max(worst, float(np.abs(traces[0][:, 1:4] - traces[1][:, 1:4]).max()))
    print(f"dead time: open-phase events {opens}, max |Δi| at the trace rows {worst:.3g} A")
    assert opens[0] > 20 and abs(opens[0] - opens[1]) <= 2
    assert worst <= 1e-6


def test_the_kernel_integrates_the_saturated_map_as_solve_ivp() -> None:
    """Each sub-interval to ≤ 1e-6 A of scipy's DOP853 at rtol 1e-12 on the same interpolant (numpy Newton
    inverse), over 40 random periods at 1500 rpm from zero current, at the period ends and at the 5 µs trace rows
    (each step's Hermite interpolant; measured: 8.3e-9 A at the ends, 1.0e-8 A at the rows; 2.1e-8 A at the
    ends without a trace, whose steps are not capped at 10 µs)."""
    from scipy.integrate import solve_ivp

    m = load_motor("niu2020-ipmsm-sat")
    assert isinstance(m, FluxMapParams)
    interp = m.interpolant
    plant = machine_for(m).build_plant(1e-4, DynoMechanics(1500.0), trace_dt_s=5e-6)
    w = m.pole_pairs * 1500.0 * 2.0 * math.pi / 60.0
    t_abs = 0.0
    worst_rows = 0.0
    rows_seen = 0
    rng = np.random.default_rng(7)
    psi = np.array(interp.flux(0.0, 0.0)[:2])
    guess = (0.0, 0.0)
    theta = 0.0
    worst = 0.0
    for _ in range(40):
        n = int(rng.integers(1, 4))
        cuts = sorted(int(c) for c in rng.integers(1, 100_000, n - 1))
        durs = [int(d) for d in np.diff([0, *cuts, 100_000])]
        states = [int(s) for s in rng.integers(0, 8, n)]
        plant.advance(states, durs)
        rows = plant.last_trace.copy()
        for st, du in zip(states, durs, strict=True):
            sa, sb, sc = (st >> 2) & 1, (st >> 1) & 1, st & 1
            va, vb = m.vdc / 3.0 * (2 * sa - sb - sc), m.vdc / math.sqrt(3.0) * (sb - sc)

            def rhs(t: float, y: np.ndarray, va: float = va, vb: float = vb, th0: float = theta) -> list[float]:
                nonlocal guess
                guess = interp.currents(float(y[0]), float(y[1]), guess)
                th = th0 + w * t
                vd, vq = va * math.cos(th) + vb * math.sin(th), -va * math.sin(th) + vb * math.cos(th)
                return [vd - m.rs * guess[0] + w * y[1], vq - m.rs * guess[1] - w * y[0]]

            inside = rows[(rows[:, 0] >= t_abs - 0.5e-9) & (rows[:, 0] < t_abs + du * 1e-9 - 0.5e-9)]
            t_eval = [*np.maximum(inside[:, 0] - t_abs, 0.0), du * 1e-9]
            sol = solve_ivp(rhs, (0.0, du * 1e-9), psi, method="DOP853", rtol=1e-12, atol=1e-13, t_eval=t_eval)
            for k, row in enumerate(inside):
                i_d, i_q = interp.currents(float(sol.y[0, k]), float(sol.y[1, k]), guess)
                th = w * row[0]
                worst_rows = max(worst_rows, abs(row[1] - (i_d * math.cos(th) - i_q * math.sin(th))))
                rows_seen += 1
            psi = sol.y[:, -1]
            theta += w * du * 1e-9
            t_abs += du * 1e-9
        ref = interp.currents(float(psi[0]), float(psi[1]), guess)
        smp = plant.sample()
        worst = max(worst, abs(smp.i_d - ref[0]), abs(smp.i_q - ref[1]))
    print(f"fluxmap kernel vs solve_ivp: max |Δi| = {worst:.3g} A at the period ends, {worst_rows:.3g} A at "
          f"{rows_seen} trace rows; steps {plant.steps}")  # type: ignore[attr-defined]
    assert worst <= 1e-6 and worst_rows <= 1e-6 and rows_seen == 40 * 20
    assert abs(smp.i_d) + abs(smp.i_q) > 1.0


def test_map_checks_refuse_bad_maps(tmp_path: Path) -> None:
    """Not monotone, not a rectangular grid, a missing column, a grid short of the trip current, a dead time in ms:
    one-line errors naming the problem."""
    lin = _linear_map()
    bad = FluxMap(lin.id_axis, lin.iq_axis, lin.psi_d.copy(), lin.psi_q, "bad")
    bad.psi_d[10, 3] = bad.psi_d[9, 3] - 0.01
    with pytest.raises(InputFileError, match="psi_d is not increasing in id"):
        check_map(interpolant(bad))
    path = tmp_path / "m.csv"
    write_csv_map(lin, path)
    lines = path.read_text(encoding="utf-8").splitlines()
    (tmp_path / "holes.csv").write_text("\n".join(lines[:-1]) + "\n", encoding="utf-8")
    with pytest.raises(InputFileError, match="do not form the rectangular grid"):
        load_interpolant(str(tmp_path / "holes.csv"))
    (tmp_path / "cols.csv").write_text("id,iq,psi_d\n0,0,0.2\n", encoding="utf-8")
    with pytest.raises(InputFileError, match="missing column"):
        load_interpolant(str(tmp_path / "cols.csv"))
    with pytest.raises(ParameterError, match="does not reach i_trip = 40 A"):
        FluxMapParams.build(flux_map=str(path), rs=1.0, pole_pairs=3, vdc=300.0, j=1e-3, i_trip=40.0)
    with pytest.raises(ParameterError, match="t_dead"):
        FluxMapParams.build(flux_map=str(path), rs=1.0, pole_pairs=3, vdc=300.0, j=1e-3, t_dead=1e-2)


def test_a_half_map_is_completed_by_symmetry(tmp_path: Path) -> None:
    """A map given for iq ≥ 0 is mirrored: ψd even, ψq odd in iq."""
    half = _linear_map(np.linspace(0.0, 36.0, 13))
    write_csv_map(half, tmp_path / "half.csv")
    interp, checks = load_interpolant(str(tmp_path / "half.csv"))
    assert interp.fmap.mirrored and checks.iq_range_a == (-36.0, 36.0)
    assert interp.flux(-5.0, -20.0)[:2] == pytest.approx((LD * -5.0 + PSI_F, LQ * -20.0), abs=1e-15)


def test_syre_mat_maps_load_in_pmsm_axes(tmp_path: Path) -> None:
    """SyR-e .mat (top-level Id, Iq, Fd, Fq, or motorModel.FluxMap_dq) in SR axes — magnet on −q — come out in PMSM
    axes (magnet on +d) and equal the same machine's CSV map."""
    from scipy.io import savemat

    ref = interpolant(_linear_map())
    # SR axes: d_sr = q_pm, q_sr = −d_pm; SyR-e gives Id_sr ≥ 0 (= iq_pm ≥ 0: the half map), Iq_sr = −id_pm
    id_sr, iq_sr = np.meshgrid(np.linspace(0.0, 36.0, 13), -GRID[::-1])
    fd_sr, fq_sr = LQ * id_sr, -(LD * (-iq_sr) + PSI_F)
    savemat(tmp_path / "fdfq_idiq_n256.mat", {"Id": id_sr, "Iq": iq_sr, "Fd": fd_sr, "Fq": fq_sr, "T": 0 * id_sr})
    savemat(tmp_path / "motor.mat", {"motorModel": {"FluxMap_dq": {"Id": id_sr, "Iq": iq_sr, "Fd": fd_sr,
                                                                    "Fq": fq_sr}, "data": {"axisType": "SR"}}})
    # a PM-axes model file (motorModel.data.axisType = 'PM'): taken as it is
    id_pm, iq_pm = np.meshgrid(GRID, np.linspace(0.0, 36.0, 13))
    savemat(tmp_path / "motor_pm.mat", {"motorModel": {"FluxMap_dq": {
        "Id": id_pm, "Iq": iq_pm, "Fd": LD * id_pm + PSI_F, "Fq": LQ * iq_pm}, "data": {"axisType": "PM"}}})
    for name in ("fdfq_idiq_n256.mat", "motor.mat", "motor_pm.mat"):
        interp, _ = load_interpolant(str(tmp_path / name))
        for i_d, i_q in ((0.0, 7.0), (-20.0, -13.0), (10.0, 30.0)):
            assert interp.flux(i_d, i_q)[:2] == pytest.approx(ref.flux(i_d, i_q)[:2], abs=1e-14)
    savemat(tmp_path / "other.mat", {"x": np.zeros(3)})
    with pytest.raises(InputFileError, match="no SyR-e flux map"):
        load_interpolant(str(tmp_path / "other.mat"))


def test_the_preset_and_its_controller_model() -> None:
    """The bundled preset loads through its kind; the controllers' linear model is the map's at the rated point
    (id = 0, 7 N·m): ψf = ψd there, Lq the secant ψq/iq, Ld the incremental ∂ψd/∂id."""
    m = load_motor("niu2020-ipmsm-sat")
    assert isinstance(m, FluxMapParams) and machine_for(m).layout.kind == "pmsm-fluxmap"
    iq_r = m.operating_point()
    assert m.torque_nm(0.0, iq_r) == pytest.approx(7.0, rel=1e-12)
    ld, lq, psi_f = m.linear_model()
    psi_d, psi_q, jac = m.interpolant.flux(0.0, iq_r)
    assert (ld, lq, psi_f) == (jac[0, 0], psi_q / iq_r, psi_d)
    assert 0.009 < ld < 0.012 and 0.012 < lq < 0.016 and 0.2 < psi_f < 0.21
    with pytest.raises(ParameterError, match="unknown motor parameter"):
        m.with_overrides({"ld": 0.01})
    assert m.with_overrides({"rs": 5.0}).rs == 5.0


def _reference_operating_point(m: FluxMapParams) -> float:
    """The rated-point bisection as it was written before the cached one: 60 halvings of `torque_nm`."""
    target, lo, hi = m.torque_rating_nm, 0.0, m.checks.iq_range_a[1]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if m.torque_nm(0.0, mid) < target else (lo, mid)
    return 0.5 * (lo + hi)


def test_the_cached_operating_point_is_the_bisection_bit_for_bit(linear_toml: Path) -> None:
    """The fit is cached per map and torque (each run asks for it twice): the same float as the plain bisection,
    for the shipped map and a linear one, a changed rated torque is a new fit, and a map too weak is refused."""
    for m in (load_motor("niu2020-ipmsm-sat"), load_motor(str(linear_toml)),
              load_motor("niu2020-ipmsm-sat", {"rated_torque_nm": 5.0})):
        assert isinstance(m, FluxMapParams)
        assert m.operating_point() == _reference_operating_point(m) == m.operating_point()
    assert load_motor("niu2020-ipmsm-sat", {"rated_torque_nm": 5.0}).operating_point() < load_motor(
        "niu2020-ipmsm-sat").operating_point()
    weak = load_motor(str(linear_toml), {"rated_torque_nm": 1e4})
    with pytest.raises(ParameterError, match="stays below the rated 10000 N·m"):
        weak.model_parameters()


def test_the_fluxmap_cli(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """`hil plant fluxmap` prints the checks of a preset (with trip coverage and the controllers' model) or a map
    file, writes a PNG, and names a missing file in one line."""
    assert main(["plant", "fluxmap", "niu2020-ipmsm-sat", "--png", str(tmp_path / "m.png")]) == 0
    out = capsys.readouterr().out
    assert "reciprocity residual" in out and "trip 30 A covered" in out and "Lq = 13.26 mH" in out
    assert (tmp_path / "m.png").stat().st_size > 1000
    assert main(["plant", "fluxmap", str(tmp_path / "none.csv")]) == 2
    err = capsys.readouterr().err
    assert "none.csv" in err and len(err.strip().splitlines()) == 1
