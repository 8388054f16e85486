"""`hil bench controllers`: C-side ns/step per implemented controller and, with valgrind, instructions/step.

Inputs are realistic: a q-current vector rotating at 1500 rpm (Ts = 100 µs) with the speed loop
active, so every stage does its normal work; three-phase controllers on the Table 3 machine at rated
current, the dual three-phase mptc1..3 on zhang2021-dtpmsm at 40 N·m with six phase currents
(`bench_machines`).
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import statistics
import subprocess
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

from pmsm_hil.app.cli.bench_machines import (
    OMEGA_M,
    SIX_PHASE_IDS,
    TS,
    BenchMachine,
    inputs,
    machine_for,
    six_phase_machine,
)
from pmsm_hil.app.cli.bench_mcu import STEP_SHARE, McuFigures, fits_ts, shortest_ts_us
from pmsm_hil.app.cli.parsing import positive_int
from pmsm_hil.hil.atomic_write import write_text_atomic
from pmsm_hil.hil.errors import HilError
from pmsm_hil.protocol.ids import ParamId
from pmsm_hil.sim_target.fw_build import Sizes

FIRMWARE_DIR = Path(__file__).resolve().parents[4] / "firmware_stub"
STAGES = ("hil_fw_stage_measure", "hil_fw_stage_reference", "hil_fw_stage_predict")
STRICT_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion",
                "-fsingle-precision-constant", "-O2"]
#: Table 4 of 000_81a00a8e308450c6.txt (dSPACE 1103), µs: measurement, reference vector, prediction, total.
PAPER_TABLE4_US: dict[str, tuple[float | None, float | None, float | None, float]] = {
    "mpcc": (7.32, 0.0, 48.51, 55.83), "fcs-mpc-1": (7.25, 5.62, 39.36, 52.23),
    "fcs-mpc-2": (7.31, 5.45, 37.43, 50.19), "dbcc-mpc": (7.29, 7.38, 36.78, 51.45), "foc": (None, None, None, 13.2),
}

# Driver for the instruction counts: same rotating input as the timing loop, plain hil_fw_step.
DRIVER_C = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "hil_fw.h"

static const float angles[%(n_phases)d] = {%(angles)s};
static const uint8_t param_ids[%(n_params)d] = {%(param_ids)s};
static const float param_values[%(n_params)d] = {%(param_values)s};

int main(int argc, char **argv)
{
    hil_fw_state_t s;
    hil_fw_cmd_t cmd;
    hil_fw_meas_t m;
    const int controller = argc > 1 ? atoi(argv[1]) : 1;
    const long steps = argc > 2 ? atol(argv[2]) : 1000;
    const float omega_m = %(omega_m).6ff;
    const float we_ts = %(we_ts).9ff;
    long k;
    int j;
    unsigned votes = 0u;
    hil_fw_init(&s);
    for (j = 0; j < %(n_params)d; ++j) {
        if (param_ids[j] != 0u && hil_fw_set_param(&s, param_ids[j], param_values[j]) != 0) {
            fprintf(stderr, "param %%u rejected\n", (unsigned)param_ids[j]);
            return 2;
        }
    }
    if (hil_fw_select_controller(&s, (uint8_t)controller) != 0) {
        fprintf(stderr, "controller %%d not implemented\n", controller);
        return 2;
    }
    hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_SPEED, omega_m + 1.0f);
    m.n_phases = %(n_phases)du;
    m.status = 0u;
    m.omega_m = omega_m;
    m.vdc = %(vdc).3ff;
    for (k = 0; k < steps; ++k) {
        const float th = we_ts * (float)(k %% 100000);
        const float al = -%(i_q).4ff * sinf(th);
        const float be = %(i_q).4ff * cosf(th);
        for (j = 0; j < %(n_phases)d; ++j) {
            m.i_abc[j] = al * cosf(angles[j]) + be * sinf(angles[j]);
        }
        m.seq = (uint16_t)k;
        m.theta_e = th;
        hil_fw_step(&s, &m, (uint64_t)k * %(ts_ns)du, &cmd);
        votes += cmd.vector_id;
    }
    printf("%%u\n", votes);
    return 0;
}
"""


def driver_source(machine: BenchMachine) -> str:
    """C driver of the instruction counts for one bench machine."""
    params = sorted(machine.params.items()) or [(0, 0.0)]
    return DRIVER_C % {
        "omega_m": OMEGA_M, "we_ts": machine.we_ts, "i_q": machine.i_q, "ts_ns": round(TS * 1e9),
        "n_phases": len(machine.angles), "angles": ", ".join(f"{a:.9f}f" for a in machine.angles),
        "n_params": len(params), "param_ids": ", ".join(f"{i}u" for i, _ in params),
        "param_values": ", ".join(f"{v:.9e}f" for _, v in params),
        "vdc": machine.params.get(int(ParamId.VDC), 300.0),
    }


@dataclass
class ControllerFigures:
    """Figures of one controller: ns/step (median over repeats of per-repeat medians)."""

    controller_id: int
    name: str
    ns_per_step: float
    ns_per_step_min_repeat: float
    split_ns: list[float]
    instructions_per_step: float | None = None
    instructions_split: list[float] = field(default_factory=list)


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `controllers` under `hil bench`."""
    p = subparsers.add_parser(
        "controllers", help="C firmware ns/step per controller (and instructions/step under valgrind)",
        description="""Time every implemented controller of the C reference firmware on a rotating rated-current vector
                       at 1500 rpm (C-side CLOCK_MONOTONIC per stage, medians over repeats); with valgrind installed
                       also count instructions per step (callgrind).""")
    p.add_argument("--steps", type=positive_int, default=20_000, metavar="N", help="steps per repeat (%(default)s)")
    p.add_argument("--repeats", type=positive_int, default=5, metavar="R", help="repeats (%(default)s)")
    p.add_argument("--valgrind-steps", type=positive_int, default=2000, metavar="N",
                   help="steps per callgrind run (%(default)s)")
    p.add_argument("--no-valgrind", action="store_true", help="skip the instruction counts")
    p.add_argument("--json", type=Path, metavar="FILE", help="also write the figures as JSON")
    p.add_argument("--board", choices=("host", "mps2-an386"), default="host",
                   help="host: this machine (ns/step, callgrind); mps2-an386: the reference firmware built for the "
                        "Cortex-M4F and run in QEMU (exact instructions/step, estimated µs at --mcu-clock, flash/RAM)")
    p.add_argument("--mcu-clock", type=float, default=168e6, metavar="HZ",
                   help="mps2-an386: MCU clock of the time estimate [Hz] (default 168e6)")
    p.add_argument("--mcu-steps", type=positive_int, default=200, metavar="N",
                   help="mps2-an386: steps per controller (default 200)")
    p.set_defaults(func=run)


def time_controller(controller_id: int, steps: int, repeats: int) -> ControllerFigures:
    """Median C-side step time [ns] of one controller over `repeats` runs of `steps` steps (on its
    `bench_machines` machine; a non-ok firmware status is an error, not a timing)."""
    from pmsm_hil.sim_target.firmware import Firmware, FirmwareError

    machine = machine_for(controller_id)
    try:
        fw = Firmware()
        for pid, value in machine.params.items():
            fw.set_param(pid, value)
        fw.select_controller(controller_id)
        fw.set_setpoint(True, 0, OMEGA_M + 1.0)
    except FirmwareError as exc:
        raise HilError(f"controller {controller_id}: {exc}") from None
    vdc = machine.params.get(int(ParamId.VDC), 300.0)
    rows = inputs(machine, steps)
    medians: list[float] = []
    splits: list[list[float]] = []
    k = 0
    for _ in range(repeats):
        totals: list[int] = []
        parts: list[tuple[int, int, int]] = []
        for currents, th in rows:
            cmd = fw.step(k & 0xFFFF, currents, th, OMEGA_M, vdc, k * 100_000)
            if cmd.status != 0:
                raise HilError(f"controller {controller_id}: firmware status {cmd.status} on the bench input")
            totals.append(cmd.exec_time_ns)
            parts.append(cmd.split_ns)
            k += 1
        medians.append(statistics.median(totals))
        splits.append([statistics.median(p[i] for p in parts) for i in range(3)])
    order = sorted(range(repeats), key=lambda r: medians[r])
    mid = order[len(order) // 2]
    from pmsm_hil.sim_target.firmware import CONTROLLERS

    name = next((c.name for c in CONTROLLERS if c.id == controller_id), str(controller_id))
    return ControllerFigures(controller_id, name, medians[mid], min(medians), splits[mid])


def _callgrind_total(driver: Path, controller_id: int, steps: int, function: str, tmp: Path) -> float:
    out = tmp / f"cg.{controller_id}.{function}.out"
    subprocess.run(
        ["valgrind", "--tool=callgrind", f"--toggle-collect={function}", f"--callgrind-out-file={out}",
         str(driver), str(controller_id), str(steps)],
        check=True, capture_output=True, timeout=600,
    )
    text = out.read_text(encoding="utf-8", errors="replace")
    match = re.search(r"^(?:summary|totals):\s+(\d+)", text, re.MULTILINE)
    if match is None:
        raise HilError(f"callgrind output {out.name}: no summary line")
    return int(match.group(1)) / steps


#: a function's inclusive cost in `callgrind_annotate --inclusive=yes`: "  176,823 (100.0%)  file:function [object]"
_INCLUSIVE = re.compile(r"^\s*([\d,]+) \([^)]*\)\s+\S*?:?(\w+) \[", re.MULTILINE)


def _callgrind_totals(driver: Path, controller_id: int, steps: int, functions: tuple[str, ...],
                      tmp: Path) -> list[float]:
    """Instructions per step inside each of `functions` (with what they call) from one callgrind run: the inclusive
    costs `callgrind_annotate` reads from its profile, what a run per function with `--toggle-collect` counts; a
    run per function where `callgrind_annotate` is not installed."""
    annotate = shutil.which("callgrind_annotate")
    if annotate is None:
        return [_callgrind_total(driver, controller_id, steps, fn, tmp) for fn in functions]
    out = tmp / f"cg.{controller_id}.out"
    subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", str(driver), str(controller_id),
                    str(steps)], check=True, capture_output=True, timeout=600)
    text = subprocess.run([annotate, "--inclusive=yes", "--threshold=100", str(out)], check=True,
                          capture_output=True, text=True, timeout=600).stdout
    inclusive: dict[str, int] = {}
    for count, name in _INCLUSIVE.findall(text):
        inclusive.setdefault(name, int(count.replace(",", "")))
    return [inclusive.get(fn, 0) / steps for fn in functions]


def count_instructions(controller_ids: list[int], steps: int) -> tuple[dict[int, list[float]], str]:
    """Instructions per step (total, measure, reference, predict) per controller, or a skip reason."""
    if shutil.which("valgrind") is None:
        return {}, "valgrind not installed: instruction counts skipped"
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        return {}, "no C compiler: instruction counts skipped"
    sources = sorted((FIRMWARE_DIR / "src").glob("*.c"))
    if not sources:
        return {}, f"firmware sources not found under {FIRMWARE_DIR}: instruction counts skipped"
    result: dict[int, list[float]] = {}
    with tempfile.TemporaryDirectory(prefix="hil-bench-") as name:
        tmp = Path(name)
        drivers: dict[str, Path] = {}
        try:
            for cid in controller_ids:
                machine = machine_for(cid)
                if machine.name not in drivers:
                    driver = tmp / f"driver{len(drivers)}"
                    error = _build_driver(cc, machine, sources, driver)
                    if error:
                        return result, error
                    drivers[machine.name] = driver
                result[cid] = _callgrind_totals(drivers[machine.name], cid, steps, ("hil_fw_step", *STAGES), tmp)
        except (subprocess.SubprocessError, OSError) as exc:
            return result, f"valgrind run failed: {exc}"
    return result, ""


def _build_driver(cc: str, machine: BenchMachine, sources: list[Path], driver: Path) -> str:
    """Compile the callgrind driver of one machine; an error text or ''."""
    driver_c = driver.with_suffix(".c")
    driver_c.write_text(driver_source(machine), encoding="utf-8")
    build = subprocess.run(
        [cc, *STRICT_FLAGS, "-I", str(FIRMWARE_DIR / "include"), "-I", str(FIRMWARE_DIR / "generated"),
         str(driver_c), *map(str, sources), "-lm", "-o", str(driver)],
        capture_output=True, text=True, timeout=300,
    )
    return f"driver build failed: {build.stderr.strip()[:500]}" if build.returncode != 0 else ""


def implemented_controllers() -> list[int]:
    """Ids (>= 1) the firmware build implements."""
    from pmsm_hil.sim_target.firmware import CONTROLLERS

    return [c.id for c in CONTROLLERS if c.id >= 1 and c.implemented]


def format_figures(figures: list[ControllerFigures], note: str) -> list[str]:
    """Printable table lines."""
    lines = [
        "controller     ns/step  (min rep)   measure  reference   predict   instr/step   "
        "(measure / reference / predict)",
    ]
    for f in figures:
        instr = "           -"
        detail = ""
        if f.instructions_per_step is not None:
            instr = f"{f.instructions_per_step:12.0f}"
            detail = "   (" + " / ".join(f"{v:.0f}" for v in f.instructions_split) + ")"
        lines.append(
            f"{f.controller_id:>2} {f.name:<10}{f.ns_per_step:9.0f}  {f.ns_per_step_min_repeat:9.0f}  "
            f"{f.split_ns[0]:8.0f}  {f.split_ns[1]:9.0f}  {f.split_ns[2]:8.0f} {instr}{detail}"
        )
    paper = [f for f in figures if f.name in PAPER_TABLE4_US]
    if paper:
        lines.append("paper Table 4 (dSPACE 1103, µs: measure / reference / predict / total):")
        for f in paper:
            parts = " / ".join("-" if v is None else f"{v:.2f}" for v in PAPER_TABLE4_US[f.name])
            lines.append(f"   {f.name:<10} {parts}")
    six = [f.name for f in figures if f.controller_id in SIX_PHASE_IDS]
    if six:
        lines.append(f"{', '.join(six)} run on {six_phase_machine().name} (six phase currents); the others on "
                     "the three-phase Table 3 machine.")
    lines.append("stage times include one CLOCK_MONOTONIC read each (~20-30 ns).")
    if note:
        lines.append(note)
    return lines


#: the control periods `hil bench controllers --board mps2-an386` says each controller fits [µs]
FITS_TS_US = (25.0, 50.0, 100.0)


def format_mcu(figures: list[McuFigures], sizes: Sizes | None, mcu_clock_hz: float, steps: int) -> list[str]:
    """Printable table of the emulated-MCU figures beside the paper's Table 4."""
    from pmsm_hil.sim_target.qemu import CPI  # numpy: imported when the figures are printed, not for the parser

    mhz = mcu_clock_hz / 1e6
    lines = [f"reference firmware on the emulated Cortex-M4F (QEMU mps2-an386), {steps} steps per controller; "
             f"time is an ESTIMATE at {mhz:g} MHz ({CPI:g} cycle/instruction, zero-wait-state lower bound)",
             f"controller   instr/step med / p99 / max     est. µs med / max @{mhz:g} MHz   own code B   "
             "paper Table 4 total µs (dSPACE 1103)"]
    for f in figures:
        paper = PAPER_TABLE4_US.get(f.name)
        ins, est = f.instructions, f.est_us
        own = "-" if f.own_flash_bytes is None else str(f.own_flash_bytes)
        lines.append(f"{f.controller_id:>2} {f.name:<10}{ins['median']:>8.0f} / {ins['p99']:>6.0f} / {ins['max']:>6.0f}"
                     f"     {est['median']:>8.2f} / {est['max']:>7.2f}        {own:>10}   "
                     f"{'-' if paper is None else f'{paper[3]:.2f}'}")
    if sizes is not None:
        lines.append(f"image (every reference controller, target core, codec, serial framing, libm): "
                     f"flash {sizes.flash} B "
                     f"(text {sizes.text} + data {sizes.data}), static RAM {sizes.ram} B (data + bss incl. the "
                     "16 KiB stack)")
    lines.append("own code: flash of the controller's source files (GNU ld map); shared files count for each user. "
                 "Instructions include the firmware API adapter (hil_app_step copying the measurement and command).")
    lines.append(f"shortest Ts: the worst step may take {STEP_SHARE:.0%} of the period (the estimate is a lower bound; "
                 "the rest is for the ADC/PWM interrupt and the link)")
    for ts_us in FITS_TS_US:
        can, cannot = fits_ts(figures, ts_us)
        too_slow = ", ".join(f"{f.name} (needs ≥ {shortest_ts_us(f):.1f} µs)" for f in cannot) or "none"
        lines.append(f"  Ts = {ts_us:g} µs ({1e3 / ts_us:g} kHz) at {mhz:g} MHz: can {', '.join(f.name for f in can)}"
                     f"{'' if can else 'none'}; cannot {too_slow}")
    return lines


def run_mcu(args: argparse.Namespace, ids: list[int]) -> int:
    """`hil bench controllers --board mps2-an386`."""
    from pmsm_hil.app.cli.bench_mcu import measure as measure_mcu
    from pmsm_hil.sim_target.firmware import CONTROLLERS
    from pmsm_hil.sim_target.qemu import CPI

    names = {c.id: c.name for c in CONTROLLERS}
    figures, sizes, per_file = measure_mcu(ids, names, args.mcu_steps, args.mcu_clock)
    for line in format_mcu(figures, sizes, args.mcu_clock, args.mcu_steps):
        print(line)
    if args.json is not None:
        payload = {"board": "mps2-an386", "steps": args.mcu_steps, "mcu_clock_hz": args.mcu_clock, "cpi": CPI,
                   "image": None if sizes is None else asdict(sizes), "files": per_file,
                   "controllers": [asdict(f) for f in figures]}
        write_text_atomic(args.json, json.dumps(payload, indent=2) + "\n", option="--json")
        print(f"figures written to {args.json}")
    return 0


def run(args: argparse.Namespace) -> int:
    """Execute `hil bench controllers`."""
    ids = implemented_controllers()
    if getattr(args, "board", "host") == "mps2-an386":
        return run_mcu(args, ids)
    figures = [time_controller(cid, args.steps, args.repeats) for cid in ids]
    note = "instruction counts skipped (--no-valgrind)"
    if not args.no_valgrind:
        counts, note = count_instructions(ids, args.valgrind_steps)
        for f in figures:
            if f.controller_id in counts:
                total, *split = counts[f.controller_id]
                f.instructions_per_step = total
                f.instructions_split = split
    for line in format_figures(figures, note):
        print(line)
    if args.json is not None:
        payload = {"steps": args.steps, "repeats": args.repeats, "note": note,
                   "controllers": [asdict(f) for f in figures]}
        write_text_atomic(args.json, json.dumps(payload, indent=2) + "\n", option="--json")
        print(f"figures written to {args.json}")
    return 0
