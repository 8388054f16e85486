"""The reference `foc` via duty cycles against its switching-state ("5-segment") form at the rated point
(docs/comparisons/foc_duty_vs_5segment.md): real closed-loop runs (C loop, in-process C firmware, lockstep, exact
plant), default motor niu2020-ipmsm, scenario `steady` (1500 rpm, 7 N·m, 0.2 s settle + 0.2 s window), Ts = 100 µs.

Rows: foc with pwm_duties 0 (the (a, b, 7) / (b, a, 0) halves, every leg switching once per control period), foc
with duties and --pwm-update single (carrier period Ts: the 7 segments every period, twice the switching) and
--pwm-update double (carrier period 2·Ts: the same switching frequency as the 5-segment form); each ideal and with
a 1 µs dead time + 0.5 µs minimum pulse.

Run: python examples/foc_duty_comparison.py [--out FILE.json]   (prints the Markdown table)
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from typing import Any

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

KEYS = ("current_thd_pct", "current_thd_total_pct", "torque_ripple_rms_nm", "torque_ripple_pp_nm",
        "switching_freq_khz", "speed_mean_rpm", "torque_mean_nm")
VARIANTS = (("5-segment (pwm_duties 0)", {"pwm_duties": 0.0}, "single"),
            ("duties, --pwm-update single", {}, "single"),
            ("duties, --pwm-update double", {}, "double"))
INVERTERS = (("ideal", 0.0, 0.0), ("t_dead 1 µs, t_mpw 0.5 µs", 1e-6, 0.5e-6))


def run_all() -> list[dict[str, Any]]:
    """One run per inverter × variant: the metrics of KEYS."""
    rows = []
    for inv_name, t_dead, t_mpw in INVERTERS:
        motor = replace(load_motor("niu2020-ipmsm"), t_dead=t_dead, t_mpw=t_mpw)
        for name, params, update in VARIANTS:
            cfg = RunConfig(motor=motor, scenario=load_scenario("steady"), controller="foc",
                            controller_params=params, pwm_update=update)
            m = run_closed_loop(cfg).metrics
            if m["end_reason"] != "completed":
                raise SystemExit(f"{inv_name} / {name}: run ended with {m['end_reason']}")
            rows.append({"inverter": inv_name, "variant": name, **{k: m[k] for k in KEYS}})
    return rows


def table(rows: list[dict[str, Any]]) -> str:
    """Markdown table of the rows."""
    head = ("| inverter | foc output | THD h2-40 % | THD all % | ripple RMS N·m | ripple p-p N·m | f_sw kHz | "
            "speed rpm | torque N·m |")
    lines = [head, "|" + "---|" * 9]
    for r in rows:
        lines.append(f"| {r['inverter']} | {r['variant']} | {r['current_thd_pct']:.2f} | "
                     f"{r['current_thd_total_pct']:.2f} | {r['torque_ripple_rms_nm']:.3f} | "
                     f"{r['torque_ripple_pp_nm']:.3f} | {r['switching_freq_khz']:.2f} | {r['speed_mean_rpm']:.1f} | "
                     f"{r['torque_mean_nm']:.3f} |")
    return "\n".join(lines)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="also write the rows as JSON here")
    args = parser.parse_args()
    result = run_all()
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            json.dump(result, fh, indent=1)
    print(table(result))
