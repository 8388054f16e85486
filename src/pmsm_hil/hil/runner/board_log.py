"""The virtual board's per-period records for the run's log (`/board/periods`, src/pmsm_hil/hil/runlog/
board_records.py): each block, the periods its link ran since the last one."""

from __future__ import annotations

import numpy as np

from pmsm_hil.hil.runlog.board_records import BOARD_DTYPE
from pmsm_hil.sim_target.stm32g4.link import BoardLink


class BoardLog:
    """Takes the board's period records of `link` not yet taken; `ts_s`: the control period [s] (their times)."""

    def __init__(self, link: BoardLink, ts_s: float) -> None:
        self.link = link
        self.ts_s = ts_s
        self.taken = 0

    def take(self) -> np.ndarray:
        """A BOARD_DTYPE block of the periods recorded since the last call (empty: none)."""
        rows = self.link.period_records(self.taken)
        block = np.zeros(len(rows), dtype=BOARD_DTYPE)
        for i, (k, isr_us, entries, load, late) in enumerate(rows):
            block[i] = (k * self.ts_s, k, isr_us, entries, load, late)
        self.taken += len(rows)
        return block
