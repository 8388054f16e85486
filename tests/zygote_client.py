"""The worker's side of a zygote process (tests/runner/foreign_zygote.py, tests/testing/pytest_zygote.py): started
on first use, asked one line at a time (one answer line each), ended with the worker."""

from __future__ import annotations

import atexit
import subprocess
import sys
import threading
from pathlib import Path


class ZygoteClient:
    """One zygote process running `script` (in `cwd`), started on first use and again if it ended; `name` names it
    in the error when it ends mid-question."""

    def __init__(self, script: str, name: str, cwd: Path | None = None) -> None:
        self.script, self.name, self.cwd = script, name, cwd
        self.proc: subprocess.Popen[str] | None = None
        self.lock = threading.Lock()

    def end(self) -> None:
        """Close its stdin and reap it: its CPU and its children's then count as the worker's children's."""
        if self.proc is not None and self.proc.stdin is not None:
            self.proc.stdin.close()
            self.proc.wait(timeout=60)

    def ask(self, line: str, env: dict[str, str] | None = None) -> str:
        """Send `line`, return the zygote's answer line (`env`: the zygote's environment when it starts)."""
        with self.lock:
            if self.proc is None or self.proc.poll() is not None:
                self.proc = subprocess.Popen([sys.executable, self.script], cwd=self.cwd, env=env,
                                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
                atexit.register(self.end)
            assert self.proc.stdin is not None and self.proc.stdout is not None
            self.proc.stdin.write(line + "\n")
            self.proc.stdin.flush()
            answer = self.proc.stdout.readline()
            assert answer, f"the {self.name}' zygote ended"
            return answer
