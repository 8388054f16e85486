"""A load beside a measurement (`hil bench realtime --load-cmd "CMD"`): another process started before the
measurement and stopped after it, with what it did meanwhile (CPU seconds it used, whether it ran throughout),
so a latency report says which load it was taken under (OSADL runs theirs beside a defined load)."""

from __future__ import annotations

import contextlib
import os
import shlex
import signal
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass

from pmsm_hil.hil.errors import ParameterError

#: the load runs this long before the measurement starts [s]
WARM_UP_S = 0.5
#: a load that ignores SIGTERM this long is killed [s]
STOP_TIMEOUT_S = 5.0


@dataclass
class LoadReport:
    """What the load did: its command, pid, CPU time [s] (its own and its waited-for children's, from
    /proc/PID/stat) over the wall time [s] it ran beside the measurement, and its exit code if it ended early."""

    command: str
    pid: int
    cpu_s: float = 0.0
    wall_s: float = 0.0
    exited_early: int | None = None

    def describe(self) -> str:
        """One line: the command and how many CPUs it kept busy on average."""
        busy = self.cpu_s / self.wall_s if self.wall_s > 0 else 0.0
        code = self.exited_early
        end = "" if code is None else f"; it EXITED early (code {code}): not a load throughout"
        return (f"load: `{self.command}` (pid {self.pid}) used {self.cpu_s:.1f} CPU-s in {self.wall_s:.1f} s "
                f"(≈ {busy:.2f} CPUs busy){end}")


def _cpu_seconds(pid: int) -> float:
    """utime + stime + cutime + cstime of `pid` [s] (0.0 when /proc does not say)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            fields = f.read().rpartition(")")[2].split()
        ticks = sum(int(v) for v in fields[11:15])  # fields 14..17 of proc(5), counted after the comm field
        return ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return 0.0


def _stop(proc: subprocess.Popen[bytes]) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(timeout=STOP_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


@contextlib.contextmanager
def load_beside(command: str | None) -> Iterator[LoadReport | None]:
    """Run `command` (split as a shell would, no shell) in its own process group for the block; stopped after
    (SIGTERM to its group, SIGKILL after STOP_TIMEOUT_S). Yields its report, filled in when the block ends;
    None without a command. A command that cannot start or exits during the warm-up is a one-line error."""
    if command is None:
        yield None
        return
    argv = shlex.split(command)
    if not argv:
        raise ParameterError("--load-cmd: empty command")
    try:
        proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, start_new_session=True)
    except OSError as exc:
        raise ParameterError(f"--load-cmd: cannot start {argv[0]!r}: {exc.strerror}") from None
    report = LoadReport(command, proc.pid)
    try:
        time.sleep(WARM_UP_S)
        if proc.poll() is not None:
            raise ParameterError(f"--load-cmd: `{command}` exited (code {proc.returncode}) before the measurement")
        t0, cpu0 = time.monotonic(), _cpu_seconds(proc.pid)
        yield report
        if proc.poll() is not None:
            report.exited_early = proc.returncode
        report.cpu_s = _cpu_seconds(proc.pid) - cpu0
        report.wall_s = time.monotonic() - t0
    finally:
        _stop(proc)
