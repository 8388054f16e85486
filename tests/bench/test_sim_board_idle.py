"""A simulated board (`hil target`, the process a labgrid place's flash starts) that waits for its host leaves the
CPU to others: between its stop checks it waits in the link's receive instead of polling it, and still answers
at once when the host comes back."""

from __future__ import annotations

import os
import socket
import time
from pathlib import Path

from pmsm_hil.bench.heartbeat import wait_heartbeat
from pmsm_hil.bench.sim_board import SimBoard
from tests.bench.labgrid_benches import free_port


def _cpu_s(pid: int) -> float:
    """User + system CPU of process `pid` so far [s]."""
    fields = Path(f"/proc/{pid}/stat").read_text(encoding="ascii").rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_an_idle_simulated_board_does_not_spin_and_still_answers() -> None:
    host, board = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_DGRAM)
    sim = SimBoard(f"udp:{board}:{host}@127.0.0.1", name="idle")
    sim.flash()
    try:
        assert wait_heartbeat(f"udp:{host}:{board}@127.0.0.1", 120.0) is not None  # started, and answered once
        assert sim.proc is not None
        cpu0, wall0 = _cpu_s(sim.proc.pid), time.monotonic()
        time.sleep(2.0)
        cpu, wall = _cpu_s(sim.proc.pid) - cpu0, time.monotonic() - wall0
        # polling, it took 1.03 CPU-s of 2 s at load 9 (a core's share); waiting, 0.01 of 3 s
        assert cpu < 0.05 * wall, f"the idle board spun: {cpu:.2f} CPU-s in {wall:.2f} s"
        assert wait_heartbeat(f"udp:{host}:{board}@127.0.0.1", 120.0) is not None  # and it answers again
        assert sim.alive()
    finally:
        sim.stop()
