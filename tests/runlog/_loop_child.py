"""Child process for the SIGKILL tests: a fake control loop submitting blocks to a RunLogger.

Usage: python _loop_child.py OUT.mcap PROGRESS.txt FLUSH_INTERVAL_S
Writes "logger PID" first, then one line "MONOTONIC_TIME LAST_SEQ" after each submitted block.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

BLOCK = 200


def main() -> None:
    from pmsm_hil.hil.runlog import RunLogger
    from tests.runlog._blocks import frame_block, period_block, trace_block

    out, progress, flush = Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3])
    with (
        progress.open("w", buffering=1) as prog,
        RunLogger(out, metadata={"test": "sigkill"}, flush_interval_s=flush) as logger,
    ):
        prog.write(f"logger {logger.pid}\n")
        start = 0
        while True:
            logger.submit_periods(period_block(start, BLOCK))
            logger.submit_frames(frame_block(start, BLOCK))
            logger.submit_trace(trace_block(start, BLOCK))
            start += BLOCK
            prog.write(f"{time.monotonic()} {start - 1}\n")
            time.sleep(0.02)


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    main()
