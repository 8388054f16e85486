"""Running `hil ...` on a pseudo-terminal (stdout and stderr a terminal of 160 columns) and reading what it drew,
each chunk with its time since the start; the status-line tests' helper."""

from __future__ import annotations

import fcntl
import os
import select
import struct
import subprocess
import sys
import termios
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


@dataclass
class PtyOutput:
    """What the command drew (chunks with their time [s] since the start) and its exit code."""

    chunks: list[tuple[float, bytes]] = field(default_factory=list)
    code: int | None = None

    @property
    def text(self) -> str:
        return b"".join(c for _, c in self.chunks).decode("utf-8", errors="replace")

    def first(self, needle: str) -> float | None:
        """Time [s] of the chunk in which `needle` was first complete; None if it never was."""
        seen = b""
        for t, chunk in self.chunks:
            seen += chunk
            if needle.encode() in seen:
                return t
        return None


def run_on_pty(argv: list[str], *, timeout_s: float = 120.0, cwd: Path | None = None) -> PtyOutput:
    """`python -m pmsm_hil.app.cli.main ARGV` with stdin, stdout and stderr on one pty; everything it drew."""
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 160, 0, 0))
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "pmsm_hil.app.cli.main", *argv], stdin=slave, stdout=slave,
                            stderr=slave, close_fds=True, cwd=cwd or ROOT, env=env)
    os.close(slave)
    out = PtyOutput()
    try:
        while time.monotonic() - t0 < timeout_s:
            ready, _, _ = select.select([master], [], [], 0.05)
            if not ready:
                if proc.poll() is not None:
                    break
                continue
            try:
                chunk = os.read(master, 65536)
            except OSError:  # EIO: the other side closed
                break
            if not chunk:
                break
            out.chunks.append((time.monotonic() - t0, chunk))
        out.code = proc.wait(timeout=max(1.0, timeout_s - (time.monotonic() - t0)))
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    return out
