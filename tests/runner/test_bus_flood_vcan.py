"""A shared bus under a measured flood on vcan0 (runs inside `.ci/vcan-vm`, the CI's SocketCAN step): a run over
`socketcan:vcan0,fd=true` with `--target external` against a native target (`hil target --native`, its own
process) while another node floods vcan0 — random ids, and the protocol's ids with random data — at 1 k frames/s
and as fast as it can write. The flood (tests/runner/bus_flood.c: an absolute schedule, so a starved vCPU under
TCG does not slow it, as it slowed `cangen -g 1` to 160 frames/s) counts the frames it wrote; its rate is that count
over its wall time, checked against vcan0's own transmit counter. Each run completes or ends naming the bus (exit
3, "bus socketcan:vcan0…"), never blaming the target, within its limits (docs/ci.md "A bus flood in the VM"; the
host-side twin on a virtual bus: tests/runner/test_shared_bus.py)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig

LINK = "socketcan:vcan0,fd=true"
VCAN = Path("/sys/class/net/vcan0")
#: the flood rate asked of the 1 k cases [frames/s], and the achieved rate's stated tolerance (±)
RATE_FPS = 1000.0
RATE_TOLERANCE = 0.2
#: a full-rate flood must reach at least this [frames/s] (the 1 k cases' upper bound: faster than asked)
FULL_RATE_MIN_FPS = RATE_FPS * (1.0 + RATE_TOLERANCE)
#: the run: foc, 0.05 s settle + 0.2 s = 2500 periods of 100 µs (the VM script's run)
RUN_OPTIONS: dict[str, Any] = {"link": LINK, "target": "external", "controller": "foc", "settle": 0.05,
                               "duration": 0.2, "loop": "native", "no_log": True}
#: wall time a run may take [s]: set-up (the ConfigAck wait, 10 s), the periods under the lockstep timeout and the
#: safe stop, on a VM under TCG (Python 10-30x slower) on a loaded host; the bug was no ending at all
RUN_LIMIT_S = 300.0

pytestmark = [
    pytest.mark.skipif(not VCAN.exists(), reason="no SocketCAN interface vcan0 (kernel without vcan)"),
]

FLOOD_SOURCE = Path(__file__).with_name("bus_flood.c")


def _tx_packets() -> int:
    return int((VCAN / "statistics" / "tx_packets").read_text())


@dataclass
class FloodCount:
    """What a flood put on the bus: its frames (counted by the flood as written), its wall time [s], vcan0's
    transmit counter over that time (every node's frames)."""

    frames: int
    wall_s: float
    bus_frames: int

    @property
    def rate_fps(self) -> float:
        return self.frames / self.wall_s


class Flood:
    """Another node flooding vcan0 (tests/runner/bus_flood.c, its own process): `rate` frames/s on an absolute
    schedule (0: as fast as it can), `kind` random or protocol ids."""

    def __init__(self, exe: Path, rate: float, kind: str) -> None:
        self.argv = [str(exe), "vcan0", f"{rate:g}", kind, "36"]

    def __enter__(self) -> Flood:
        self.tx0 = _tx_packets()
        self.proc = subprocess.Popen(self.argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        return self

    def stop(self) -> FloodCount:
        self.proc.send_signal(signal.SIGTERM)
        out, _ = self.proc.communicate(timeout=30)
        text = out.decode(errors="replace")
        match = re.search(r"sent (\d+) frames in ([0-9.]+) s", text)
        assert self.proc.returncode == 0 and match, (self.argv, self.proc.returncode, text)
        return FloodCount(int(match[1]), float(match[2]), _tx_packets() - self.tx0)

    def __exit__(self, *exc: object) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


@pytest.fixture(scope="module")
def flood_exe(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """bus_flood.c built with the project's strict C flags."""
    exe = tmp_path_factory.mktemp("flood") / "bus_flood"
    cc = os.environ.get("CC", "cc")
    subprocess.run([cc, "-std=c99", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-O2", "-o", str(exe),
                    str(FLOOD_SOURCE)], check=True)
    return exe


@pytest.fixture(scope="module")
def native_target(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """One `hil target --native` on vcan0 for every case, started before any flood and awaited without the spawn's
    60 s ready-line limit (Python starts 10-30x slower under TCG)."""
    out = tmp_path_factory.mktemp("target") / "target.out"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    with out.open("wb") as f:
        proc = subprocess.Popen([sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--native", "--link", LINK,
                                 "--idle-timeout", "1800"], stdout=f, stderr=subprocess.STDOUT, env=env)
    try:
        t0 = time.monotonic()
        while b"ready" not in out.read_bytes():
            assert proc.poll() is None, f"the target ended: {out.read_text(errors='replace')[-500:]}"
            assert time.monotonic() - t0 < 900, "the target did not start within 900 s"
            time.sleep(0.5)
        yield
    finally:
        proc.terminate()
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _run(exe: Path, rate: float, kind: str) -> tuple[dict[str, Any], FloodCount, float]:
    cfg = RunConfig.from_options(RUN_OPTIONS)
    with Flood(exe, rate, kind) as flood:
        time.sleep(1.0)  # the flood at its rate before the run starts
        t0 = time.monotonic()
        metrics = run_closed_loop(cfg).metrics
        run_s = time.monotonic() - t0
        count = flood.stop()
    return metrics, count, run_s


def _report(case: str, m: dict[str, Any], count: FloodCount, run_s: float) -> str:
    line = (f"bus-flood {case}: {count.frames} frames in {count.wall_s:.1f} s = {count.rate_fps:.0f} frames/s "
            f"(vcan0 tx {count.bus_frames}); run exit {m['end_code']} in {run_s:.1f} s, periods {m['total_periods']},"
            f" bus_foreign_frames {m['bus_foreign_frames']}, bus_suspect_frames {m['bus_suspect_frames']}, "
            f"kernel_dropped {(m.get('link') or {}).get('kernel_dropped')}: {m['end_reason']}")
    print(line)
    return line


def _never_the_target(m: dict[str, Any], line: str) -> None:
    """Completed, or ended naming the bus (exit 3): never a DUT-violation ending, a target fault or a silent target,
    and no finding (the `missing` finding an ending the bus takes over is not the target's: it is taken back)."""
    assert m["end_code"] in (EndCode.COMPLETED, EndCode.SAFETY_STOP), line
    if m["end_code"] == EndCode.SAFETY_STOP:
        assert m["end_reason"].startswith("bus socketcan:vcan0"), line  # the link's description
    assert m["dut_violations"] == 0, line


def _counted(count: FloodCount, m: dict[str, Any], line: str) -> None:
    """The flood's own count and the bus's agree: vcan0 carried the flood's frames plus the run's."""
    assert count.frames > 0, line
    assert count.bus_frames >= count.frames + m["link"]["frames_tx"], line


@pytest.mark.usefixtures("native_target")
@pytest.mark.parametrize("kind", ["random", "protocol"])
def test_vcan_a_measured_1k_flood_never_blames_the_target(flood_exe: Path, kind: str) -> None:
    """A flood of 1 k frames/s (achieved: within ±20 %) of random ids, or of the protocol's ids with random data:
    the run completes or ends naming the bus; the host counted other nodes' frames as the bus's."""
    m, count, run_s = _run(flood_exe, RATE_FPS, kind)
    line = _report(f"{kind}-1k", m, count, run_s)
    _counted(count, m, line)
    assert abs(count.rate_fps - RATE_FPS) <= RATE_TOLERANCE * RATE_FPS, line
    _never_the_target(m, line)
    assert m["bus_foreign_frames"] + m["bus_suspect_frames"] > 0, line
    assert run_s < RUN_LIMIT_S, line


@pytest.mark.usefixtures("native_target")
@pytest.mark.parametrize("kind", ["random", "protocol"])
def test_vcan_a_full_rate_flood_ends_within_the_limits(flood_exe: Path, kind: str) -> None:
    """As fast as the flood can write (measured: above the 1 k cases' band): the run completes or ends naming the
    bus, within the run's limits (no receive that never ends)."""
    m, count, run_s = _run(flood_exe, 0.0, kind)
    line = _report(f"full-{kind}", m, count, run_s)
    _counted(count, m, line)
    assert count.rate_fps > FULL_RATE_MIN_FPS, line
    _never_the_target(m, line)
    assert run_s < RUN_LIMIT_S, line
