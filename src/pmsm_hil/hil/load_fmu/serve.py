"""The load FMU's own process (`--load-fmu-isolation process`): `python -m pmsm_hil.hil.load_fmu.serve SHM_FD
PARENT_PID` serves the mailbox of the shared memory file SHM_FD (src/pmsm_hil/hil/runner/c/loop_fmu_box.c nl_fmu_serve:
the FMU's binary opened, instantiated, initialised and stepped here, on the run's requests) until the run closes it
or PARENT_PID exits. Ctrl-C from the terminal is the run's to handle: ignored here."""

from __future__ import annotations

import signal
import sys


def main(argv: list[str] | None = None) -> int:
    """Serve; 0 when the run closed the FMU, 1 when the run's process went, 2 on bad arguments."""
    args = sys.argv[1:] if argv is None else argv
    try:
        shm_fd, parent_pid = int(args[0]), int(args[1])
    except (IndexError, ValueError):
        print("usage: python -m pmsm_hil.hil.load_fmu.serve SHM_FD PARENT_PID", file=sys.stderr)
        return 2
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from pmsm_hil.hil._loop_native import lib

    rc = int(lib.nl_fmu_serve(shm_fd, parent_pid))
    return 2 if rc < 0 else rc


if __name__ == "__main__":
    sys.exit(main())
