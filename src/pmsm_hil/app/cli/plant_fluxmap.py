"""`hil plant fluxmap PATH`: print (and optionally plot) the load checks of a flux map (kind "pmsm-fluxmap")."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from pmsm_hil.hil.errors import InputFileError
from pmsm_hil.hil.presets_loader import load_motor

if TYPE_CHECKING:  # the flux map's modules (numpy) are imported when a map is checked
    from pmsm_hil.hil.fluxmap import Interpolant, MapChecks
    from pmsm_hil.hil.fluxmap_params import FluxMapParams


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `fluxmap` under `hil plant`."""
    p = subparsers.add_parser("fluxmap", help="check a flux map (CSV, SyR-e .mat, or a pmsm-fluxmap motor)",
                              description="""Print a flux map's load checks: grid, monotonicity, incremental
                                             inductances, reciprocity residual |∂ψd/∂iq − ∂ψq/∂id|; with a pmsm-fluxmap
                                             motor (preset or TOML) also the trip-current coverage, the torque
                                             1.5·p·(ψd·iq − ψq·id) and the controllers' linear model.""")
    p.add_argument("path", help="flux map (.csv with id,iq,psi_d,psi_q or SyR-e .mat), motor TOML or preset name")
    p.add_argument("--png", type=Path, default=None, help="also plot ψd, ψq against the currents to this PNG")
    p.set_defaults(func=run)


def _lines(interp: Interpolant, c: MapChecks) -> list[str]:
    fmap = interp.fmap
    return [
        f"flux map {fmap.source}",
        f"  grid: {len(fmap.id_axis)} id × {len(fmap.iq_axis)} iq; id {c.id_range_a[0]:g}..{c.id_range_a[1]:g} A, "
        f"iq {c.iq_range_a[0]:g}..{c.iq_range_a[1]:g} A" + (" (iq < 0 by d-axis symmetry)" if fmap.mirrored else ""),
        f"  flux at zero current: ψd = {c.psi_at_zero_wb[0]:.6g} Wb, ψq = {c.psi_at_zero_wb[1]:.3g} Wb",
        f"  monotone: yes (smallest secants ∂ψd/∂id {1e3 * c.min_secant_dd_h:.4g} mH, ∂ψq/∂iq "
        f"{1e3 * c.min_secant_qq_h:.4g} mH); smallest det L_inc {c.min_det_h2:.4g} H²",
        f"  reciprocity residual |∂ψd/∂iq − ∂ψq/∂id|: max {1e3 * c.reciprocity_max_h:.4g} mH, RMS "
        f"{1e3 * c.reciprocity_rms_h:.4g} mH ({100 * c.reciprocity_rel:.3g} % of the mean self-inductance)",
        f"  largest ‖L_inc⁻¹‖∞ at the nodes: {c.inv_l_max:.4g} 1/H",
    ]


def _motor_lines(m: FluxMapParams) -> list[str]:
    c = m.checks
    ld, lq, psi_f = m.linear_model()
    return [
        f"motor {m.name}: trip {m.i_trip:g} A " + ("covered by the grid (−id, ±iq)" if c.covers(m.i_trip)
                                                    else "NOT covered by the grid"),
        f"  rated torque {m.torque_rating_nm:.4g} N·m = 1.5·p·(ψd·iq − ψq·id) at id = 0, iq = "
        f"{m.operating_point():.4g} A",
        f"  controllers' linear model there: Ld = {1e3 * ld:.4g} mH (incremental), Lq = {1e3 * lq:.4g} mH "
        f"(secant), ψf = {psi_f:.5g} Wb",
    ]


def _plot(interp: Interpolant, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pmsm_hil.app.compare.plot import save_figure

    fmap = interp.fmap
    fig, (ax_d, ax_q) = plt.subplots(1, 2, figsize=(10, 4))
    for k in range(0, len(fmap.iq_axis), max(1, len(fmap.iq_axis) // 6)):
        ax_d.plot(fmap.id_axis, fmap.psi_d[:, k], label=f"iq = {fmap.iq_axis[k]:g} A")
    for k in range(0, len(fmap.id_axis), max(1, len(fmap.id_axis) // 6)):
        ax_q.plot(fmap.iq_axis, fmap.psi_q[k, :], label=f"id = {fmap.id_axis[k]:g} A")
    ax_d.set(xlabel="id [A]", ylabel="ψd [Wb]", title="ψd(id)")
    ax_q.set(xlabel="iq [A]", ylabel="ψq [Wb]", title="ψq(iq)")
    for ax in (ax_d, ax_q):
        ax.grid(True)
        ax.legend(fontsize=7)
    save_figure(plt, fig, out, 100, f"--png {out}")


def run(args: argparse.Namespace) -> int:
    """Execute `hil plant fluxmap`."""
    from pmsm_hil.hil.fluxmap import load_interpolant
    from pmsm_hil.hil.fluxmap_params import KIND, FluxMapParams

    path = Path(args.path)
    motor = None
    if path.suffix.lower() in (".csv", ".mat"):
        interp, checks = load_interpolant(str(path))
    else:
        params = load_motor(args.path)
        if not isinstance(params, FluxMapParams):
            raise InputFileError(f"{args.path}: a {type(params).__name__} motor, not kind = \"{KIND}\"")
        motor, (interp, checks) = params, load_interpolant(params.flux_map)
    lines = _lines(interp, checks) + (_motor_lines(motor) if motor is not None else [])
    print("\n".join(lines))
    if args.png is not None:
        _plot(interp, args.png)
        print(f"plot -> {args.png}")
    return 0
