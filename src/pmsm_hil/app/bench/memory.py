"""`hil bench memory`: peak resident memory and wall time of `hil run` against the simulated duration.

Each duration runs in a fresh interpreter (`python -m pmsm_hil.app.bench.memory`, the probe) that calls the
CLI's `run` and reports its own peak RSS (`ru_maxrss`) and that of its children (the MCAP logger process),
so one measurement never inherits another's heap.
"""

from __future__ import annotations

import itertools
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

#: goal: a 600 s run under this peak RSS [MB]
RSS_GOAL_MB = 500.0
#: goal: wall time linear in duration — the marginal wall time per simulated second between consecutive
#: durations may differ by at most this fraction (a fixed start-up cost is allowed; growth is not)
LINEARITY_GOAL = 0.10
#: goal in real time: the longest run's RSS within this fraction of the shortest's
RT_GROWTH_GOAL = 0.10


@dataclass(frozen=True)
class MemoryPoint:
    """One `hil run` of `duration_s` simulated seconds: wall time [s] and peak RSS [MB]."""

    duration_s: float
    wall_s: float
    #: CPU time of the run's process (user + system) [s]: less sensitive than wall time to other load
    cpu_s: float
    periods: int
    rss_host_mb: float
    rss_logger_mb: float
    exit_code: int

    @property
    def wall_per_sim_s(self) -> float:
        """Wall seconds per simulated second."""
        return self.wall_s / self.duration_s


def marginal_rates(points: list[MemoryPoint], *, cpu: bool = False) -> list[float]:
    """Wall (or CPU) seconds per extra simulated second between consecutive durations (sorted by duration)."""
    ordered = sorted(points, key=lambda p: p.duration_s)
    costs = [p.cpu_s if cpu else p.wall_s for p in ordered]
    return [(costs[i + 1] - costs[i]) / (b.duration_s - a.duration_s)
            for i, (a, b) in enumerate(itertools.pairwise(ordered)) if b.duration_s > a.duration_s]


def _own_peak_rss_kib(fallback_kib: float) -> float:
    """This process's own peak RSS [KiB]: Linux's VmHWM, which starts anew at exec. `ru_maxrss` does not: a process
    forked from a big one (a pytest worker that ran a browser test) and exec'd keeps its parent's peak."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return float(line.split()[1])
    except OSError:
        pass
    return fallback_kib


def probe(argv: list[str]) -> dict[str, float]:
    """Run `hil run ARGV` here and return wall time, exit code and peak RSS of this process and its children."""
    from pmsm_hil.app.cli.main import main

    t0, c0 = time.perf_counter(), time.process_time()
    code = main(["run", *argv])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    kib = 1024.0 if sys.platform != "darwin" else 1.0
    return {"exit_code": float(code), "wall_s": wall, "cpu_s": cpu,
            "rss_host_mb": _own_peak_rss_kib(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * kib / 1024.0)
            * 1024.0 / 1e6,
            "rss_logger_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * kib / 1e6}


def measure(duration_s: float, *, log: bool, log_trace: bool, controller: str, settle_s: float = 0.1,
            mode: str = "lockstep") -> MemoryPoint:
    """One probe run of `duration_s` s (plus `settle_s`) in a fresh interpreter, in `mode` (lockstep or realtime)."""
    with tempfile.TemporaryDirectory(prefix="hil-bench-memory-") as tmp:
        metrics = Path(tmp) / "metrics.json"
        argv = ["--duration", repr(duration_s), "--settle", repr(settle_s), "--controller", controller,
                "--mode", mode, "--json", str(metrics)]
        argv += ["--out", str(Path(tmp) / "run")] if log else ["--no-log"]
        if log and log_trace:
            argv.append("--log-trace")
        proc = subprocess.run([sys.executable, "-m", "pmsm_hil.app.bench.memory", *argv], capture_output=True,
                              text=True, env=dict(os.environ), check=False)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
        if not lines:
            raise RuntimeError(f"memory probe for {duration_s:g} s failed (exit {proc.returncode}): "
                               f"{proc.stderr.strip().splitlines()[-1:] or proc.stdout[-200:]}")
        fig = json.loads(lines[-1])
        periods = json.loads(metrics.read_text())["total_periods"] if metrics.exists() else 0
    return MemoryPoint(duration_s, fig["wall_s"], fig["cpu_s"], int(periods), fig["rss_host_mb"], fig["rss_logger_mb"],
                       int(fig["exit_code"]))


def realtime_growth(points: list[MemoryPoint]) -> tuple[float, float] | None:
    """(RSS of the longest run / RSS of the shortest − 1, growth [MB per minute of run]) of host + logger; None with
    fewer than two durations."""
    if len(points) < 2:
        return None
    short, long = min(points, key=lambda p: p.duration_s), max(points, key=lambda p: p.duration_s)
    a, b = short.rss_host_mb + short.rss_logger_mb, long.rss_host_mb + long.rss_logger_mb
    minutes = (long.duration_s - short.duration_s) / 60.0
    return b / a - 1.0, (b - a) / minutes if minutes > 0 else 0.0


def format_points(points: list[MemoryPoint], *, realtime: bool = False) -> list[str]:
    """The table, the linearity figures (lockstep) or the RSS growth (`realtime`) and the verdict against the
    goals."""
    lines = [f"{'simulated s':>11}  {'wall s':>8}  {'wall/sim':>8}  {'CPU s':>8}  {'CPU/sim':>8}  {'host RSS MB':>11}  "
             f"{'logger RSS MB':>13}  exit"]
    for p in points:
        lines.append(f"{p.duration_s:>11g}  {p.wall_s:>8.1f}  {p.wall_per_sim_s:>8.3f}  {p.cpu_s:>8.1f}  "
                     f"{p.cpu_s / p.duration_s:>8.3f}  {p.rss_host_mb:>11.0f}  {p.rss_logger_mb:>13.0f}  {p.exit_code}")
    if len(points) >= 2:
        longest = max(points, key=lambda p: p.duration_s)
        total = longest.rss_host_mb + longest.rss_logger_mb
        lines.append(f"peak RSS of the longest run ({longest.duration_s:g} s), host + logger: {total:.0f} MB "
                     f"(goal < {RSS_GOAL_MB:g} MB) — {'met' if total < RSS_GOAL_MB else 'NOT met'}")
    growth = realtime_growth(points) if realtime else None
    if growth is not None:
        short, long = min(points, key=lambda p: p.duration_s), max(points, key=lambda p: p.duration_s)
        lines.append(f"real time: RSS (host + logger) of the {long.duration_s:g} s run vs the {short.duration_s:g} s "
                     f"run: {growth[0]:+.1%}, {growth[1]:+.2f} MB/min (goal within {RT_GROWTH_GOAL:.0%}) — "
                     + ("met" if abs(growth[0]) <= RT_GROWTH_GOAL else "NOT met"))
    for label, cpu in (() if realtime else (("wall", False), ("CPU", True))):
        rates = marginal_rates(points, cpu=cpu)
        if len(rates) >= 2:
            spread = max(rates) / min(rates) - 1.0 if min(rates) > 0 else float("inf")
            lines.append(f"marginal {label} time per simulated second between consecutive durations: "
                         + ", ".join(f"{r:.3f}" for r in rates)
                         + f" (spread {spread:.1%}, goal within {LINEARITY_GOAL:.0%}) — "
                         + ("met" if spread <= LINEARITY_GOAL else "NOT met"))
    lines.append(f"machine load (1/5/15 min): {' '.join(f'{x:.2f}' for x in os.getloadavg())} on {os.cpu_count()} CPUs")
    return lines


def to_dict(points: list[MemoryPoint]) -> dict[str, object]:
    """The figures as JSON-ready data."""
    return {"points": [asdict(p) | {"wall_per_sim_s": p.wall_per_sim_s} for p in points],
            "rss_goal_mb": RSS_GOAL_MB, "linearity_goal": LINEARITY_GOAL, "loadavg": list(os.getloadavg())}


if __name__ == "__main__":
    print(json.dumps(probe(sys.argv[1:])))
