"""Run two controllers on the same scenario through the library API and compare their metrics
(what `hil run` does, without the CLI): mpcc vs dsvm-20 on the niu2020 IPMSM at 1500 rpm, 7 N·m.

Run: python examples/closed_loop_api.py [--duration S]
"""

from __future__ import annotations

import argparse
from typing import Any

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario


def main(duration_s: float) -> dict[str, dict[str, Any]]:
    """Print a small table; returns the metrics per controller."""
    scenario = load_scenario("steady").with_overrides(speed_rpm=1500.0, load_nm=7.0, duration_s=duration_s)
    results = {}
    for controller in ("mpcc", "dsvm-20"):
        cfg = RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=scenario, controller=controller)
        results[controller] = run_closed_loop(cfg).metrics
    print(f"{'controller':<10} {'torque N·m':>10} {'ripple RMS':>10} {'THD %':>7} {'f_av kHz':>8}")
    for name, m in results.items():
        print(f"{name:<10} {m['torque_mean_nm']:>10.3f} {m['torque_ripple_rms_nm']:>10.3f} "
              f"{m['current_thd_pct']:>7.2f} {m['switching_freq_khz']:>8.2f}")
    return results


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration", type=float, default=0.2, help="metrics window [s]")
    main(parser.parse_args().duration)
