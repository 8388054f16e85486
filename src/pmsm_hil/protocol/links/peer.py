"""Start an echo peer (`links.echo`) in another process and wait until it is ready."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Sequence

from pmsm_hil.protocol.errors import LinkError


class EchoPeer:
    """Context manager owning one echo subprocess; `pass_fds` hands descriptors (pty masters) over."""

    def __init__(
        self,
        spec: str,
        *,
        pass_fds: Sequence[int] = (),
        idle_timeout_s: float = 10.0,
        ready_timeout_s: float = 20.0,
    ) -> None:
        self._proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "pmsm_hil.protocol.links.echo",
                spec,
                "--idle-timeout",
                str(idle_timeout_s),
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            pass_fds=tuple(pass_fds),
        )
        deadline = time.monotonic() + ready_timeout_s
        line = self._proc.stdout.readline() if self._proc.stdout is not None else ""
        if line.strip() != "ready" or time.monotonic() > deadline:
            err = self._proc.stderr.read() if self._proc.stderr is not None else ""
            self.close()
            raise LinkError(f"echo peer for {spec!r} did not start: {err.strip() or line.strip()}")

    def close(self) -> None:
        """Stop the peer (terminate if it has not exited) and reap it."""
        if self._proc.poll() is None:
            self._proc.terminate()
        try:
            self._proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        for stream in (self._proc.stdout, self._proc.stderr):
            if stream is not None:
                stream.close()

    def __enter__(self) -> EchoPeer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
