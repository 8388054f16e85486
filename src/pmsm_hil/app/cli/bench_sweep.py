"""`hil bench sweep`: wall time of one 16-run sweep plan on 1 and on 2 local workers, and their ratio."""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

from pmsm_hil.app.cli.parsing import positive_float, positive_int

#: the plan: 2 controllers × 2 loads × 4 initial rotor angles = 16 runs
CONTROLLERS = ("mpcc", "dsvm-20")
LOADS = ("3", "7")
ANGLES = 4


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `bench sweep`."""
    p = subparsers.add_parser(
        "sweep", help="speed-up of `hil sweep` with 2 local workers against 1 (same 16-run plan)",
        description="""Runs one 16-run sweep plan (controllers mpcc, dsvm-20 × load 3, 7 N·m × 4 initial rotor angles;
                       --sim seconds simulated each, half settling) on the local process pool with 1 and with 2 workers,
                       alternately, --repeat times (worker start-up included; one untimed warm-up run first starts the
                       pool's fork server), and prints the median wall times, the ratio 2 workers / 1 worker (ideal 0.5;
                       the goal is ≤ 0.6 on an idle 2-core machine) and the load average before and after: a shared
                       machine makes the figures noisy. Also checks that both give the same metrics (wall-clock ones
                       aside), and prints how many cores were busy during the 1-worker rounds (/proc/stat): the native
                       loop runs its periods in a thread of its own beside the Python side, so one worker uses more than
                       one core and 2 workers on 2 cores cannot reach 0.5 (`--loop python` measures the pool with
                       one-thread runs).""")
    p.add_argument("--repeat", type=positive_int, default=3, metavar="N", help="rounds (default %(default)s)")
    p.add_argument("--sim", type=positive_float("--sim"), default=0.2, metavar="S",
                   help="simulated seconds per run (default %(default)s)")
    p.add_argument("--loop", choices=("auto", "native", "python"), default="auto",
                   help="the runs' period loop, as `hil run --loop` (default %(default)s)")
    p.set_defaults(func=run)


def _busy_cpu_s() -> float:
    """CPU time [s] all processes of the machine have used since boot (/proc/stat; 0 where it is missing): the pool's
    workers are children of its fork server, not of this process, so their own usage is not visible here."""
    try:
        with open("/proc/stat", encoding="ascii") as fh:
            fields = [int(x) for x in fh.readline().split()[1:9]]
    except (OSError, ValueError):
        return 0.0
    idle = fields[3] + fields[4]  # idle + iowait
    return (sum(fields) - idle) / os.sysconf("SC_CLK_TCK")


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def run(args: argparse.Namespace) -> int:
    """Execute `hil bench sweep`."""
    from pmsm_hil.app.sweep.configure import base_options, build_runs
    from pmsm_hil.app.sweep.engines import LocalEngine
    from pmsm_hil.app.sweep.execute import tasks_for
    from pmsm_hil.app.sweep.rows import deterministic_view
    from pmsm_hil.app.sweep.task import run_task

    half = args.sim / 2
    base = base_options({"duration": half, "settle": half, "loop": args.loop})
    runs = build_runs(base, [(("controller", c), ("load", x)) for c in CONTROLLERS for x in LOADS], ANGLES)
    tasks = tasks_for(runs, None)
    print(f"hil bench sweep: {len(tasks)} runs ({', '.join(CONTROLLERS)} × load {', '.join(LOADS)} N·m × {ANGLES} "
          f"rotor angles, {args.sim:g} s simulated each, --loop {args.loop}) on the local process pool; "
          f"{os.cpu_count()} cores")
    with LocalEngine(1) as engine:  # warm-up, not timed: the pool's fork server starts once per process
        list(engine.map_unordered(run_task, tasks[:1]))
    print(f"load average before (1/5/15 min): {_load()}")
    times: dict[int, list[float]] = {1: [], 2: []}
    cores: list[float] = []  # cores one worker used, per round
    rows: dict[int, dict[str, dict[str, object]]] = {}
    for k in range(args.repeat):
        for workers in ((1, 2) if k % 2 == 0 else (2, 1)):
            t0, cpu0 = time.perf_counter(), _busy_cpu_s()
            with LocalEngine(workers) as engine:
                got = {tasks[i].run_id: row for i, row, error in engine.map_unordered(run_task, tasks)
                       if error is None}
            times[workers].append(time.perf_counter() - t0)
            if workers == 1:
                cores.append((_busy_cpu_s() - cpu0) / times[1][-1])
            rows.setdefault(workers, got)
        print(f"round {k + 1}: 1 worker {times[1][-1]:.2f} s, 2 workers {times[2][-1]:.2f} s, "
              f"ratio {times[2][-1] / times[1][-1]:.3f}; load {_load()}", flush=True)
    one, two = statistics.median(times[1]), statistics.median(times[2])
    same = (len(rows[1]) == len(tasks) and rows[1].keys() == rows[2].keys()
            and all(deterministic_view(rows[1][r]) == deterministic_view(rows[2][r]) for r in rows[1]))
    failed = sum(1 for r in rows[1].values() if r.get("end_code") != 0)
    print(f"median wall time: 1 worker {one:.2f} s, 2 workers {two:.2f} s")
    used = statistics.median(cores)
    print(f"cores busy during the 1-worker rounds: {used:.2f} (median, whole machine: the worker and any other "
          f"load); with 2 cores the best ratio is about {min(max(used, 1.0), 2.0) / 2.0:.2f}")
    print(f"ratio 2 workers / 1 worker: {two / one:.3f} (ideal 0.5; goal ≤ 0.6 on an idle 2-core machine)")
    print(f"metrics identical on 1 and 2 workers: {'yes' if same else 'NO'}; runs that did not complete: {failed}")
    print(f"load average after (1/5/15 min): {_load()}")
    if not same:
        print("hil: bench sweep: 1 and 2 workers gave different metrics", file=sys.stderr)
        return 1
    return 0
