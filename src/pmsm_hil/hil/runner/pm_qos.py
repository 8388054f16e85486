"""The CPUs' wake-up latency held low for a real-time run: a PM QoS request through `/dev/cpu_dma_latency`, as
cyclictest's `--latency` makes it.

An idle CPU goes to a sleep state (on a VM: the vCPU halts and the hypervisor deschedules it); waking it for a
frame or a timer then costs the state's exit latency, on the VMs measured here 40–60 µs for a blocked receive
(docs/benchmarks.md). While a process keeps this file open with a 32-bit value written to it, the kernel keeps
every CPU out of idle states whose exit latency is above that many µs — with 0, idle CPUs poll: a blocked
receive of a UDP round trip here then wakes in ~5 µs (round trip 53 → 9.5 µs). Idle CPUs then burn power; the
request ends when the file is closed (at the run's end, or when the process dies). Opening the file needs root
(mode 0600): refused, the run goes on and says so in its warnings.
"""

from __future__ import annotations

import contextlib
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass

#: the kernel's PM QoS interface for the CPUs' wake-up latency (Documentation/power/pm_qos_interface.rst)
PM_QOS_FILE = "/dev/cpu_dma_latency"
#: `--cpu-dma-latency` value that leaves the kernel's setting alone
LEAVE = -1


@dataclass(frozen=True, slots=True)
class CpuLatencyHold:
    """What became of a request: `held_us` the latency held [µs] (None: not held), `refused` why not (None:
    held, or not asked for)."""

    held_us: int | None
    refused: str | None = None

    def warning(self, option: str = "--cpu-dma-latency") -> str | None:
        """One line for the run's warnings when the request was refused, else None."""
        if self.refused is None:
            return None
        return (f"{option}: the CPUs' wake-up latency was not held ({self.refused}): an idle CPU may wake tens of "
                "µs late for a frame (docs/runner.md, qualifying a bench PC)")


@contextlib.contextmanager
def cpu_latency_held(latency_us: int, path: str | None = None) -> Iterator[CpuLatencyHold]:
    """Hold the CPUs' wake-up latency at most `latency_us` µs for the block (`LEAVE`: do nothing) through `path`
    (None: `PM_QOS_FILE`)."""
    path = PM_QOS_FILE if path is None else path
    if latency_us == LEAVE:
        yield CpuLatencyHold(None)
        return
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CLOEXEC)
    except OSError as exc:
        why = "needs root" if isinstance(exc, PermissionError) else exc.strerror or str(exc)
        yield CpuLatencyHold(None, f"{path}: {why}")
        return
    try:
        try:
            os.write(fd, struct.pack("=i", latency_us))
        except OSError as exc:
            yield CpuLatencyHold(None, f"{path}: {exc.strerror or exc}")
            return
        yield CpuLatencyHold(latency_us)
    finally:
        os.close(fd)
