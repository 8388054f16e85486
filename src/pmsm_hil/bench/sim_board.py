"""A simulated board: a `hil target` process serving its link, started with the image it is "flashed" with (a SIL
library, `hil target --sil IMAGE`; none: the reference firmware). What a debug probe's load is on a real bench."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

from pmsm_hil.bench.errors import BenchError

#: how long a simulated board serves without a frame before it ends itself [s]
IDLE_TIMEOUT_S = 600.0


class SimBoard:
    """One `hil target` process on `target_link` (the board's end of the link); `flash(image)` (re)starts it."""

    def __init__(self, target_link: str, name: str = "board") -> None:
        self.target_link = target_link
        self.name = name
        self.proc: subprocess.Popen[bytes] | None = None

    def flash(self, image: str | Path | None = None) -> None:
        """Stop the running board, if any, and start it again with `image`."""
        self.stop()
        cmd = [sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--link", self.target_link,
               "--idle-timeout", f"{IDLE_TIMEOUT_S:g}"]
        if image is not None:
            path = Path(image)
            if not path.is_file():
                raise BenchError(f"board {self.name}: image {path} is not a file")
            cmd += ["--sil", str(path)]
        self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     start_new_session=True)

    def alive(self) -> bool:
        """The board's process runs."""
        return self.proc is not None and self.proc.poll() is None

    def stop(self) -> None:
        """End the board's process (SIGTERM, then SIGKILL after 5 s)."""
        proc, self.proc = self.proc, None
        if proc is None or proc.poll() is not None:
            return
        os.kill(proc.pid, signal.SIGTERM)
        try:
            proc.wait(5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
