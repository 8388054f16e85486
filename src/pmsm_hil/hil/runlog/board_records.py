"""`/board/periods`: what the virtual board's MCU did in each control period of an `stm32g4:` run, one JSON message
per period `{"period", "t", "isr_us", "isr_entries", "cpu_load", "late_compares"}` — t: the period's start [s],
isr_us: cycles in interrupt handlers / HCLK [µs] (the Command's exec_time_ns), isr_entries: exception entries,
cpu_load: share of the period's cycles not asleep in WFI/WFE, late_compares: 1 when the TIM1 compare values of the
period were written after the update event that followed their ADC trigger (they apply a period late);
src/pmsm_hil/hil/runner/board_log.py takes them from the board's link block by block."""

from __future__ import annotations

import json
from typing import Final

import numpy as np

from pmsm_hil.hil.runlog import layouts

#: seq: the control period (the message's sequence number)
BOARD_DTYPE: Final = np.dtype([("t", "f8"), ("seq", "u4"), ("isr_us", "f8"), ("isr_entries", "u4"),
                               ("cpu_load", "f8"), ("late_compares", "u4")])

BOARD_JSON_SCHEMA: Final = layouts.BOARD_JSON_SCHEMA


def encode_board(block: np.ndarray) -> list[bytes]:
    """One compact JSON object per BOARD_DTYPE record."""
    return [json.dumps({"period": int(r["seq"]), "t": float(r["t"]), "isr_us": float(r["isr_us"]),
                        "isr_entries": int(r["isr_entries"]), "cpu_load": float(r["cpu_load"]),
                        "late_compares": int(r["late_compares"])}, separators=(",", ":")).encode() for r in block]
