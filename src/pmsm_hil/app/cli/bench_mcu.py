"""The MCU half of `hil bench controllers --board mps2-an386`: every reference controller's exact instructions
per step on the emulated Cortex-M4F (QEMU mps2-an386, plugin counts), the execution-time estimate at the MCU
clock, and flash/RAM of the reference firmware image and of each controller's own source files (GNU ld map).

Inputs are `bench_machines`' rotating rated-current vector at 1500 rpm (the host bench's), sent as
Measurement frames over the emulated UART; one QEMU per bench machine (three-phase, dual three-phase).
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from pmsm_hil.app.cli.bench_machines import OMEGA_M, TS, BenchMachine, inputs, machine_for
from pmsm_hil.hil.errors import HilError
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.ids import ParamId
from pmsm_hil.protocol.messages import Command, ConfigAck, ConfigParam, Fault, Measurement, Measurement6, Setpoint
from pmsm_hil.sim_target.fw_build import Sizes, build_firmware

if TYPE_CHECKING:  # numpy, QEMU's target and the links (python-can) are imported when the bench runs
    import numpy as np

    from pmsm_hil.sim_target.qemu import QemuTarget

#: each controller's own source files (shared helpers named too; the core, codec, state, step, transforms
#: and libm are the common part of the image)
CONTROLLER_FILES: dict[str, tuple[str, ...]] = {
    "mpcc": ("mpcc.c",), "fcs-mpc-1": ("fcs_mpc.c", "dsvm.c"), "fcs-mpc-2": ("fcs_mpc.c", "dsvm.c"),
    "dsvm-20": ("dsvm.c",), "dbcc-mpc": ("dbcc_mpc.c", "dsvm.c"), "foc": ("foc.c",),
    "mptc1": ("mptc1.c", "mptc_common.c", "six.c"), "mptc2": ("mptc2.c", "mptc_common.c", "six.c"),
    "mptc3": ("mptc3.c", "mptc_common.c", "six.c"), "3vmpc": ("three_vmpc.c", "hv_mpfc.c"),
    "hv-mpfc": ("hv_mpfc.c",), "im-foc": ("im_foc.c", "foc.c"),
}
REPLY_TIMEOUT_S = 5.0


@dataclass
class McuFigures:
    """One controller on the emulated MCU: instructions per step and the estimate at the MCU clock."""

    controller_id: int
    name: str
    instructions: dict[str, float]
    est_us: dict[str, float]
    own_flash_bytes: int | None = None
    own_files: list[str] = field(default_factory=list)


#: share of the control period the controller's step may take on the MCU (docs/runner.md, "Control periods below
#: 100 µs"): the estimate is a lower bound (1 cycle per instruction) and the rest of the period belongs to the
#: ADC/PWM interrupt and the link
STEP_SHARE = 0.5


def shortest_ts_us(f: McuFigures) -> float:
    """The shortest control period [µs] this controller's worst estimated step allows (max / STEP_SHARE)."""
    return f.est_us["max"] / STEP_SHARE


def fits_ts(figures: list[McuFigures], ts_us: float) -> tuple[list[McuFigures], list[McuFigures]]:
    """(the controllers that can run at Ts = `ts_us` µs, those that cannot), in the order given."""
    return ([f for f in figures if shortest_ts_us(f) <= ts_us], [f for f in figures if shortest_ts_us(f) > ts_us])


def map_sizes(map_file: Path) -> dict[str, dict[str, int]]:
    """Per object file (by source name, e.g. 'mpcc.c'): bytes of text/rodata (flash), data, bss kept by the
    linker, from a GNU ld map file."""
    text = map_file.read_text(encoding="utf-8", errors="replace")
    start = text.find("Linker script and memory map")
    lines = text[start:].splitlines() if start >= 0 else []
    out: dict[str, dict[str, int]] = {}
    pending: str | None = None
    pat = re.compile(r"^\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S+)$")
    full = re.compile(r"^ (\.\S+)\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S+)$")
    for line in lines:
        m = full.match(line)
        if m:
            section, size, obj = m.group(1), int(m.group(3), 16), m.group(4)
        elif pending is not None and (m2 := pat.match(line)):
            section, size, obj = pending, int(m2.group(2), 16), m2.group(3)
        else:
            pending = line.strip() if re.match(r"^ \.\S+$", line) else None
            continue
        pending = None
        name = Path(obj.split("(")[0]).name.removesuffix(".obj").removesuffix(".o")
        kind = ("flash" if section.startswith((".text", ".rodata")) else
                "data" if section.startswith(".data") else "bss" if section.startswith(".bss") else None)
        if kind is not None and size:
            sizes = out.setdefault(name, {"flash": 0, "data": 0, "bss": 0})
            sizes[kind] += size
    return out


def _serve(qemu: QemuTarget, machine: BenchMachine, ids: list[int], steps: int) -> None:
    """Configure, enable each controller in turn and run `steps` measurements through it."""
    from pmsm_hil.protocol.links import open_link

    link = open_link(qemu.link_spec, "host")
    codec = FrameCodec("canfd")
    dec = codec.decoder(ordered=False)
    try:
        def wait(kind: type, what: str) -> object:
            end = time.monotonic() + REPLY_TIMEOUT_S
            while time.monotonic() < end:
                frame = link.poll()
                msg = dec.feed(frame) if frame is not None else None
                if isinstance(msg, Fault):
                    raise HilError(f"mps2-an386 bench: firmware fault {msg.code} on {what}")
                if isinstance(msg, kind):
                    return msg
            raise HilError(f"mps2-an386 bench: no {kind.__name__} for {what} within {REPLY_TIMEOUT_S:g} s")

        params = {int(ParamId.TS): TS, **machine.params}
        for pid, value in params.items():
            link.send(codec.encode(ConfigParam(param_id=pid, value=value)))
            ack = wait(ConfigAck, f"parameter {pid}")
            if ack.status != 0:  # type: ignore[attr-defined]
                raise HilError(f"mps2-an386 bench: parameter {pid} = {value} rejected")
        rows = inputs(machine, steps)
        vdc = machine.params.get(int(ParamId.VDC), 300.0)
        seq = 0
        for cid in ids:
            link.send(codec.encode(Setpoint(enable=False, mode=0, reference=0.0, controller_id=cid)))
            link.send(codec.encode(Setpoint(enable=True, mode=0, reference=OMEGA_M + 1.0, controller_id=cid)))
            for currents, th in rows:
                i = currents
                if len(i) == 6:
                    m: Measurement | Measurement6 = Measurement6(
                        seq=seq & 0xFFFF, i_a=i[0], i_b=i[1], i_c=i[2], i_u=i[3], i_v=i[4], i_w=i[5], theta_e=th,
                        omega_m=OMEGA_M, vdc=vdc, status=0)
                else:
                    m = Measurement(seq=seq & 0xFFFF, i_a=i[0], i_b=i[1], i_c=i[2], theta_e=th, omega_m=OMEGA_M,
                                    vdc=vdc, status=0)
                link.send(codec.encode(m))
                cmd = wait(Command, f"controller {cid} step {seq}")
                if cmd.status != 0:  # type: ignore[attr-defined]
                    raise HilError(f"mps2-an386 bench: controller {cid}: firmware status {cmd.status}")  # type: ignore[attr-defined]
                seq += 1
    finally:
        link.close()


def measure(ids: list[int], names: dict[int, str], steps: int, mcu_clock_hz: float
            ) -> tuple[list[McuFigures], Sizes | None, dict[str, dict[str, int]]]:
    """Figures of every controller id on the emulated MCU, the image sizes and the per-file sizes."""
    from pmsm_hil.sim_target.qemu import CPI, QemuTarget, stats

    build = build_firmware("mps2-an386")
    groups: dict[str, list[int]] = {}
    machines: dict[str, BenchMachine] = {}
    for cid in ids:
        machine = machine_for(cid)
        groups.setdefault(machine.name, []).append(cid)
        machines[machine.name] = machine
    counts: dict[int, np.ndarray] = {}
    for name, group in groups.items():
        qemu = QemuTarget(build.path, mcu_clock_hz=mcu_clock_hz)
        try:
            _serve(qemu, machines[name], group, steps)
            all_counts = qemu.instruction_counts()
        finally:
            qemu.close()
        if len(all_counts) != steps * len(group):
            raise HilError(f"mps2-an386 bench: {len(all_counts)} instruction counts for {steps * len(group)} steps")
        for i, cid in enumerate(group):
            counts[cid] = all_counts[i * steps:(i + 1) * steps]
    map_file = build.path.with_suffix(".map")
    per_file = map_sizes(map_file) if map_file.is_file() else {}
    figures = []
    for cid in ids:
        ins = stats(counts[cid])
        est = {k: v * CPI / mcu_clock_hz * 1e6 for k, v in ins.items()}
        files = list(CONTROLLER_FILES.get(names[cid], ()))
        own = sum(per_file.get(f, {}).get("flash", 0) for f in files) if per_file else None
        figures.append(McuFigures(cid, names[cid], ins, est, own, files))
    return figures, build.sizes, per_file
