"""What each link fault class does to torque and currents for the reference firmware: real runs, one per fault,
printed as the Markdown table of docs/fault_effects.md.

Run: `python -m pmsm_hil.app.bench.fault_effects [--duration S] [--controller NAME]` (lockstep, in-process
target, niu2020 IPMSM at 1500 rpm / 7 N·m; findings tolerated and the watchdog widened so every run goes to
the end and the effect is measured, not the first finding).
"""

from __future__ import annotations

import argparse
from typing import Any

from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig

#: (label, --fault spec) of the table rows; seed 1 each
CASES = (
    ("none", ""),
    ("drop 1 %", "drop=0.01"),
    ("drop 5 %", "drop=0.05"),
    ("dup 5 %", "dup=0.05"),
    ("corrupt 1 % (CRC drops)", "corrupt=0.01"),
    ("reorder 5 %", "reorder=0.05"),
    ("delay 40 µs each way", "delay=40us"),
    ("delay 60 µs each way", "delay=60us"),
    ("jitter 0-60 µs each way", "jitter=60us"),
    ("silence 10 ms", "silence=0.2:0.21"),
)


def run_case(spec: str, *, controller: str, duration_s: float) -> dict[str, Any]:
    """Metrics of one run with fault `spec` ("" = none)."""
    values = {"motor": "niu2020-ipmsm", "speed": 1500.0, "load": 7.0, "settle": 0.1, "duration": duration_s,
              "controller": controller, "fault": f"{spec},seed=1" if spec else "", "tolerate": 10**9,
              "watchdog_periods": 10**9, "no_log": True}
    sources = {key: "fault_effects case" for key in values if key not in ("duration", "controller")}  # else options
    return run_closed_loop(RunConfig.from_options(values, sources)).metrics


def _cell(value: Any, fmt: str) -> str:
    return "–" if value is None else format(value, fmt)


def table(controller: str, duration_s: float) -> list[str]:
    """Markdown lines: one row per fault case."""
    lines = ["| fault | missing / other findings | injected | torque ripple RMS [N·m] | torque error [N·m] | "
             "speed error [%] | current THD h2–40 [%] | THD all [%] | end |",
             "|---|---|---|---|---|---|---|---|---|"]
    print("\n".join(lines), flush=True)
    for label, spec in CASES:
        m = run_case(spec, controller=controller, duration_s=duration_s)
        missing = m["dut_violations_by_rule"]["missing"]
        faults = m["link_faults"] or {}
        injected = ", ".join(f"{k} {v}" for k, v in faults.items() if v) or "–"
        lines.append(f"| {label} | {missing} / {m['dut_violations'] - missing} | {injected} | "
                     f"{_cell(m['torque_ripple_rms_nm'], '.3f')} | {_cell(m['torque_error_mean_nm'], '+.3f')} | "
                     f"{_cell(m['speed_error_pct'], '+.2f')} | {_cell(m['current_thd_pct'], '.2f')} | "
                     f"{_cell(m['current_thd_total_pct'], '.2f')} | {m['end_reason'][:40]} |")
        print(lines[-1], flush=True)
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pmsm_hil.app.bench.fault_effects", description=__doc__)
    ap.add_argument("--duration", type=float, default=0.5, help="metrics window [s] (default 0.5)")
    ap.add_argument("--controller", default="mpcc", help="reference controller (default mpcc)")
    args = ap.parse_args(argv)
    table(args.controller, args.duration)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
