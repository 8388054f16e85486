"""`/target/console`: the lines a target process wrote (a SIL firmware's `printf`), one JSON message per line
`{"t", "seq", "stream", "text"}` — t: seconds since the target process started (wall time), seq: the line's
number in the run, stream: "stdout" or "stderr"; src/pmsm_hil/hil/runner/target_console.py collects them."""

from __future__ import annotations

import json
from typing import Final

import numpy as np

from pmsm_hil.hil.runlog import layouts

#: longest line kept [bytes] (the rest of a longer line is cut)
MAX_LINE_BYTES: Final = 240
STREAM_STDOUT: Final = 1
STREAM_STDERR: Final = 2
STREAM_NAMES: Final = {STREAM_STDOUT: "stdout", STREAM_STDERR: "stderr"}

CONSOLE_DTYPE: Final = np.dtype([("t", "f8"), ("seq", "u4"), ("stream", "u1"), ("length", "u2"),
                                 ("text", f"S{MAX_LINE_BYTES}")])

CONSOLE_JSON_SCHEMA: Final = layouts.CONSOLE_JSON_SCHEMA


def encode_console(block: np.ndarray) -> list[bytes]:
    """One compact JSON object per CONSOLE_DTYPE record."""
    return [json.dumps({"t": float(r["t"]), "seq": int(r["seq"]), "stream": STREAM_NAMES.get(int(r["stream"]), "?"),
                        "text": bytes(r["text"][: int(r["length"])]).decode(errors="replace")},
                       separators=(",", ":")).encode() for r in block]
