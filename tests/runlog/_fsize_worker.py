"""The logger process under a file size limit (`HIL_TEST_FSIZE` bytes): its writes past it fail with EFBIG,
as on a full disk they fail with ENOSPC (RLIMIT_FSIZE needs no root, unlike a small tmpfs)."""

from __future__ import annotations

import os
import resource
import signal
from typing import Any

from pmsm_hil.hil.runlog.worker import run_worker


def limited_worker(*args: Any) -> None:
    """`run_worker` with RLIMIT_FSIZE set (SIGXFSZ ignored, so a write past it fails instead of killing)."""
    limit = int(os.environ["HIL_TEST_FSIZE"])
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    run_worker(*args)
