"""The load FMU's process, seen from the run (`--load-fmu-isolation process`, the default): a shared memory file
holding the mailbox of src/pmsm_hil/hil/runner/c/loop_fmu_box.c, `python -m pmsm_hil.hil.load_fmu.serve` started on it,
and a pipe whose write end only that process holds (it hangs up when the process ends, however it ends). The C side
then waits for each answer at most `--step-timeout`, and never past the process's death or `stop()`."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
from typing import Any

from pmsm_hil.hil.load_fmu.errors import LoadFmuStepError

#: wall time [s] the FMU's process gets to start serving (a Python start-up on a loaded machine)
START_TIMEOUT_S = 60.0
#: how often the start-up is looked at [s]
START_POLL_S = 0.002
#: wall time [s] the FMU's process gets to exit after the run closed the FMU before it is killed
CLOSE_WAIT_S = 1.0


class LoadFmuProcess:
    """The process serving one load FMU instance, its mailbox mapped into `fmu` (an nl_fmu_t *)."""

    def __init__(self, lib: Any, fmu: Any, timeout_s: float) -> None:
        self._shm = os.memfd_create("hil-load-fmu", os.MFD_CLOEXEC)
        self._death = -1
        self.proc: subprocess.Popen[bytes] | None = None
        try:
            os.ftruncate(self._shm, int(lib.nl_fmu_box_size()))
            self._death, alive = os.pipe()
            try:
                self.proc = subprocess.Popen(
                    [sys.executable, "-m", "pmsm_hil.hil.load_fmu.serve", str(self._shm), str(os.getpid())],
                    stdin=subprocess.DEVNULL, pass_fds=(self._shm, alive))
            finally:
                os.close(alive)
            if lib.nl_fmu_box_attach(fmu, self._shm, self._death, int(timeout_s * 1e9)) != 0:
                raise OSError("cannot map the load FMU's mailbox")
            self._wait_ready(lib, fmu)
        except BaseException:
            self.close(kill=True)
            raise

    def _wait_ready(self, lib: Any, fmu: Any) -> None:
        """Until the process serves (LoadFmuStepError if it ends or takes longer than START_TIMEOUT_S)."""
        assert self.proc is not None
        deadline = time.monotonic() + START_TIMEOUT_S
        while not lib.nl_fmu_box_ready(fmu):
            rc = self.proc.poll()
            if rc is not None:
                raise LoadFmuStepError(f"the load FMU's process ended at start-up ({describe_exit(rc)})")
            if time.monotonic() > deadline:
                raise LoadFmuStepError(f"the load FMU's process did not start within {START_TIMEOUT_S:g} s")
            time.sleep(START_POLL_S)

    def exit_status(self) -> int | None:
        """The process's exit status once it ended (it is reaped; waits up to CLOSE_WAIT_S for a dying one),
        None while it runs."""
        if self.proc is None:
            return None
        with contextlib.suppress(subprocess.TimeoutExpired):
            return self.proc.wait(CLOSE_WAIT_S)
        return None

    def close(self, *, kill: bool) -> None:
        """End the process (killed at once with `kill`, else after CLOSE_WAIT_S) and close the descriptors;
        twice is fine."""
        proc = self.proc
        if proc is not None and proc.poll() is None:
            if not kill:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.wait(CLOSE_WAIT_S)
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        for fd in (self._shm, self._death):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._shm = self._death = -1


def describe_exit(returncode: int) -> str:
    """`SIGSEGV` for a death by signal 11, `exit code 0` for an exit (src/pmsm_hil/hil/runner/sil_watch.py's
    wording)."""
    from pmsm_hil.hil.runner.sil_watch import describe_exit as describe

    return describe(returncode)
