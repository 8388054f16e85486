"""Run-logger throughput benchmark (prints figures; asserts completeness only, no timing assertions).

Run with `pytest tests/runlog/test_benchmark.py -s` or `python -m tests.runlog.test_benchmark`.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from pmsm_hil.hil.runlog import RunLogger
from tests.runlog._blocks import frame_block, period_block, trace_block

BLOCK = 1000


def _busy_loop(periods: int, work_s: float, logger: RunLogger | None, blocks: list[Any]) -> float:
    """Fake control loop: busy-waits `work_s` per period, submits a block every BLOCK periods; rate (1/s)."""
    start = time.perf_counter()
    for k in range(periods // BLOCK):
        for _ in range(BLOCK):
            end = time.perf_counter() + work_s
            while time.perf_counter() < end:
                pass
        if logger is not None:
            p, f, t = blocks[k % len(blocks)]
            logger.submit_periods(p)
            logger.submit_frames(f)
            logger.submit_trace(t)
    return periods / (time.perf_counter() - start)


def benchmark(tmp_dir: Path, blocks_n: int = 20, compression: str = "lz4") -> dict[str, float]:
    """Caller cost per 1000-period block, logger throughput, loop-rate loss at a 20 kHz fake loop."""
    blocks = [
        (period_block(k * BLOCK, BLOCK), frame_block(k * BLOCK, BLOCK), trace_block(k * BLOCK, BLOCK))
        for k in range(4)
    ]
    res: dict[str, float] = {}
    # 1) caller cost, logger paced well below its limit
    costs: dict[str, list[float]] = {"periods": [], "frames": [], "trace": []}
    with RunLogger(tmp_dir / "a.mcap", metadata={}, compression=compression) as lg:
        for k in range(blocks_n):
            p, f, t = blocks[k % 4]
            for name, fn, blk in (
                ("periods", lg.submit_periods, p),
                ("frames", lg.submit_frames, f),
                ("trace", lg.submit_trace, t),
            ):
                s = time.perf_counter()
                fn(blk)
                costs[name].append(time.perf_counter() - s)
            time.sleep(0.03)
    for name, v in costs.items():
        res[f"caller_{name}_us_per_block_median"] = float(np.median(v)) * 1e6
    # 2) logger throughput: submit as fast as possible, time until the file is finalised
    start = time.perf_counter()
    with RunLogger(
        tmp_dir / "b.mcap", metadata={}, compression=compression, ring_bytes=256 * 1024 * 1024
    ) as lg:
        for k in range(blocks_n):
            p, f, t = blocks[k % 4]
            lg.submit_periods(p)
            lg.submit_frames(f)
            lg.submit_trace(t)
    elapsed = time.perf_counter() - start
    stats = lg.final_stats or {}
    res["logger_periods_per_s_end_to_end"] = blocks_n * BLOCK / elapsed
    res["logger_periods_per_busy_s"] = blocks_n * BLOCK / max(float(stats.get("busy_s", elapsed)), 1e-9)
    res["file_bytes_per_period"] = (tmp_dir / "b.mcap").stat().st_size / (blocks_n * BLOCK)
    res["periods_written"] = float(stats.get("periods", 0))
    # 3) loop-rate loss of a fake 20 kHz loop (≈ 45 µs of work per period)
    base = _busy_loop(blocks_n * BLOCK, 45e-6, None, blocks)
    with RunLogger(tmp_dir / "c.mcap", metadata={}, compression=compression) as lg:
        logged = _busy_loop(blocks_n * BLOCK, 45e-6, lg, blocks)
        res["stall_s"] = lg.stall_s
    res["loop_rate_hz_without_logger"] = base
    res["loop_rate_hz_with_logger"] = logged
    res["loop_rate_loss_pct"] = 100.0 * (1.0 - logged / base)
    return res


def test_benchmark_runlog(tmp_path: Path) -> None:
    """Every part of the benchmark runs and the logger writes every period; the figures themselves come from the
    command (`python -m tests.runlog.test_benchmark`, 40 blocks), so the test's four blocks (each block once) keep
    its fake loop's busy-waiting short."""
    res = benchmark(tmp_path, blocks_n=4)
    print()
    for key, value in res.items():
        print(f"  {key:40s} {value:12.1f}")
    assert res["periods_written"] == 4 * BLOCK
    assert res["caller_periods_us_per_block_median"] > 0.0


if __name__ == "__main__":
    import sys
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        for comp in sys.argv[1:] or ["lz4"]:
            print(comp)
            for key, value in benchmark(Path(d), blocks_n=40, compression=comp).items():
                print(f"  {key:40s} {value:12.1f}")
