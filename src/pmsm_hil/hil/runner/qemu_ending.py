"""How a run on an emulated MCU (`--target qemu:FW.elf`) ended, told apart: the firmware faulted (its fault
handler reports pc, lr, CFSR and HFSR on the semihosting console and ends QEMU with exit code 64 + the exception
number, board.h; the reason names the function at the pc), the firmware hung (QEMU alive and the guest executing
instructions all along, no Command), or QEMU itself died (a signal, another exit code: its stderr says why). Each
is `EndCode.SAFETY_STOP` (exit 3) with its own reason; a dead QEMU is no longer an internal error. A QEMU that idles
(the firmware waits for a frame that was lost) keeps the loop's ending."""

from __future__ import annotations

import time

from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.loop_outcome import LoopOutcome
from pmsm_hil.hil.runner.sil_watch import cpu_s, describe_exit, ended_silent, ending_place, silent_since
from pmsm_hil.sim_target.qemu import QemuTarget

#: without the instruction-count plugin: a QEMU that used at least this share of one CPU while watched is executing
#: (the firmware computes): a spinning guest measured 30 % (QEMU -icount on a loaded 2-core machine), one waiting in
#: WFI for a frame ~0
BUSY_SHARE = 0.1
#: with the plugin: a guest that executed at least this many instructions while watched is executing (one waiting in
#: WFI or in a blocking doorbell read executes none; a spinning one millions per second of QEMU's CPU)
BUSY_INSTRUCTIONS = 1000
#: how long QEMU is watched [s] (the CPU time counts in 10 ms ticks)
WATCH_S = 0.5


def _watch(qemu: QemuTarget, seconds: float) -> tuple[int | None, bool]:
    """(QEMU's exit status if it ends within `seconds`, whether the guest executed meanwhile: BUSY_INSTRUCTIONS of
    its own, or without the plugin BUSY_SHARE of QEMU's CPU)."""
    proc = qemu.process
    assert proc is not None
    t0, cpu0, insns0 = time.monotonic(), cpu_s(proc.pid), qemu.executed_instructions()
    deadline = t0 + seconds
    while time.monotonic() < deadline:
        rc = proc.poll()
        if rc is not None:
            return rc, False
        time.sleep(0.01)
    insns1 = qemu.executed_instructions()
    if insns0 is not None and insns1 is not None:
        return proc.poll(), insns1 - insns0 >= BUSY_INSTRUCTIONS
    cpu1 = cpu_s(proc.pid)
    busy = cpu0 is not None and cpu1 is not None and cpu1 - cpu0 >= BUSY_SHARE * (time.monotonic() - t0)
    return proc.poll(), busy


def judge_qemu(qemu: QemuTarget, out: LoopOutcome, timeout_s: float) -> None:
    """Rewrite the ending `out` in place when QEMU exited or the firmware hung (see the module); an interrupted
    run stays interrupted."""
    proc = qemu.process
    if proc is None or out.end_code == EndCode.INTERRUPTED:
        return
    rc, busy = proc.poll(), False
    link_failed = out.end_code == EndCode.INTERNAL_ERROR  # e.g. a broken pipe: QEMU's socket closed
    if rc is None and (ended_silent(out) or link_failed):
        rc, busy = _watch(qemu, WATCH_S)
    period, where = silent_since(out), ending_place(out)
    if rc is not None:
        fault = qemu.fault_description(rc)
        if fault is not None:
            reason = f"target {fault} {where}: the firmware's fault handler stopped the MCU"
        else:
            tail = qemu.stderr_tail()
            reason = f"QEMU died ({describe_exit(rc)} {where}){': ' + tail if tail else ''}"
        out.error = None
    elif busy and ended_silent(out):
        reason = (f"target hung: its step for period {period if period is not None else '?'} did not return within "
                  f"--lockstep-timeout {timeout_s:g} s (the emulated MCU's own time; it kept executing)")
    else:
        return
    out.end_code = int(EndCode.SAFETY_STOP)
    out.end_reason = f"{reason}; inverter put in the safe state (zero vector)"
    out.safe_state = True
