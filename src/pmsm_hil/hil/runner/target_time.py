"""The target's own time while the host waits for its answer, for a wait in Python (the safe stop's confirmation):
the C loop's rule for its wait for a Command (`nl_own_time_t`, src/pmsm_hil/hil/runner/c/loop_stall.h), called
through the loop's extension. A target process the host observes (a SIL target process, a spawned `hil target`)
counts the CPU time its process got and the time it slept with nothing to do; an emulated MCU (QEMU with the
instruction-count plugin) its executed instructions and QEMU's idle sleep. Time the host kept it stopped
(SIGSTOP) or off the CPUs counts for nothing: a host stall, not the firmware's silence (docs/runner.md "Host
stalls").
"""

from __future__ import annotations

import time
from typing import Any, Final

#: the wait is read in slices this long [s] (loop_stall.h NL_STALL_SLICE_NS); a quarter of a shorter timeout
STALL_SLICE_S: Final = 0.02


class TargetTime:
    """The own time of the target in process `pid` since `start()` [s], read at most every slice: `had_s` after
    `step()`. `guest_insns_address` / `ns_per_insn`: an emulated MCU's running instruction count in shared memory
    and the virtual time of one instruction [ns] (0: none, the process's time counts). A process that cannot be
    read (gone, or no /proc) leaves `observable` false: the caller then counts wall time."""

    def __init__(self, pid: int, timeout_s: float, guest_insns_address: int = 0, ns_per_insn: int = 0) -> None:
        from pmsm_hil.hil._loop_native import ffi, lib

        self._ffi, self._lib = ffi, lib
        self.pid = pid
        self.slice_s = min(STALL_SLICE_S, timeout_s / 4)
        self._guest: Any = (ffi.cast("const uint64_t *", guest_insns_address) if guest_insns_address
                            else ffi.NULL)
        self._ns_per_insn = int(ns_per_insn) if guest_insns_address else 0
        self._own = ffi.new("nl_own_time_t *")
        self._next = 0.0
        self.observable = pid > 0
        self.start()

    @property
    def guest(self) -> bool:
        """An emulated MCU judged by its own progress (its instructions and idle time)."""
        return self._ns_per_insn > 0

    def start(self) -> None:
        """Start counting now."""
        self._lib.nl_own_time_start(self._own, self.pid, self._guest, self._ns_per_insn, int(self.slice_s * 1e9),
                                    self._lib.nl_now_ns())
        self._next = time.monotonic() + self.slice_s

    def step(self) -> None:
        """Read the process when a slice has passed since the last reading (cheap otherwise)."""
        if not self.observable or time.monotonic() < self._next:
            return
        self._next = time.monotonic() + self.slice_s
        if self._lib.nl_own_time_step(self._own, self._lib.nl_now_ns()) != 0:
            self.observable = False

    @property
    def had_s(self) -> float:
        """The target's own time since `start()` as of the last reading [s]."""
        return int(self._own.had_ns) / 1e9

    @property
    def watching(self) -> bool:
        """The process was read at least once after the first slice."""
        return bool(self._own.watching)


def target_time(pid: int, timeout_s: float, guest: tuple[int, int] = (0, 0)) -> TargetTime | None:
    """A `TargetTime` for the target in process `pid` (0: None, no process to observe: a board, an external
    target, the in-process target), `guest` the emulated MCU's (count address, ns per instruction) or (0, 0)."""
    if pid <= 0:
        return None
    return TargetTime(pid, timeout_s, guest[0], guest[1])


__all__ = ["STALL_SLICE_S", "TargetTime", "target_time"]
