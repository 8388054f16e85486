"""Suite-wide checks. In CI (`HIL_CI=1`, set by .ci/run) a skip is a failure unless its reason is one CI
cannot provide: a missing C toolchain, cmake, valgrind, Chromium or the rerun CLI must not silently turn
tests off there."""

from __future__ import annotations

import gc
import os
import resource
import signal
import sys
from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.hil.runner.reference_loop import ENV as REFERENCE_LOOP_ENV
from pmsm_hil.hil.runner.reference_loop import register_reference_loop
from tests.oracle.closed_loop import run_reference_loop

# `--loop python`: the Python reference loop the C loop is proven against (not part of the product), in this
# process and in the `hil` processes the tests start
register_reference_loop(run_reference_loop)
os.environ[REFERENCE_LOOP_ENV] = str(Path(__file__).resolve().parent / "oracle" / "closed_loop.py")

#: Skip reasons CI accepts: hardware this kernel lacks, and the optional benchmark extra.
CI_ALLOWED_SKIPS = (
    "no SocketCAN interface",  # no vcan module on the CI kernel; runs on users' Linux CI
    "gym-electric-motor not installed",  # optional [bench] extra, not installed by CI
    "labgrid is not installed",  # optional [bench] extra (tests/bench: the simulated labgrid benches)
    "multicast",  # loopback multicast is not routed on every host
    # python-can's own skips in its back-to-back tests (tests/protocol/test_python_can_conformance.py), and the one
    # test a point-to-point link cannot run (a third bus on one end's channel)
    "TODO: how shall this be treated if sending messages locally",
    "the timing sensitive behaviour cannot be reproduced reliably on a CI server",
    "a point-to-point link has two ends",
)

_unexpected: list[str] = []


def _hypothesis_without_wall_clock_limits() -> None:
    """Hypothesis's per-example deadline (200 ms) and its too-slow health check measure wall time: beside load 11
    one example of tests/protocol/test_codec.py::test_command_exact took 1001 ms once (0.29 ms on the retry) and
    failed the suite. What the properties check does not depend on time, so the suite's profile has no deadline
    and no too-slow check (a test's own @settings still sets the rest)."""
    from hypothesis import HealthCheck, settings

    settings.register_profile("hil-suite", deadline=None, suppress_health_check=[HealthCheck.too_slow])
    settings.load_profile("hil-suite")


_hypothesis_without_wall_clock_limits()


def pytest_configure(config: pytest.Config) -> None:
    """Give the session Python's own Ctrl-C handling when its launcher ignored SIGINT (a background job of a
    non-interactive shell, `cmd &` in a script, starts with SIGINT ignored, and Python then installs no handler).
    The suite tests Ctrl-C: `main()` must find `default_int_handler`, and the processes the tests interrupt with
    SIGINT inherit the ignored disposition, so they would not stop (hil replay/sweep/run timed out or exited 0)."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    _cache_bytecode()
    if os.environ.get("HIL_CPU_REPORT") and _CPU_REPORT_OWNER not in os.environ:
        os.environ[_CPU_REPORT_OWNER] = str(os.getpid())


def _cache_bytecode() -> None:
    """Where PYTHONDONTWRITEBYTECODE is set, the suite's Python processes (xdist workers, `hil` commands, spawned
    targets, pytest sessions) cache their bytecode below the user's cache folder instead (PYTHONPYCACHEPREFIX;
    nothing is written into the tree): otherwise each of the suite's few thousand processes compiles the package's
    ~200 modules again, ~0.5 CPU-s of the ~1.4 a `hil` start-up costs (docs/ci.md, "The project's own suite")."""
    if not (sys.dont_write_bytecode or os.environ.get("PYTHONDONTWRITEBYTECODE")):
        return  # bytecode is written beside the sources as usual
    from pmsm_hil.sim_target.fw_build import cache_dir

    prefix = os.environ.get("PYTHONPYCACHEPREFIX") or str(cache_dir() / "pycache")
    os.environ["PYTHONPYCACHEPREFIX"] = prefix
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    sys.pycache_prefix = prefix
    sys.dont_write_bytecode = False


def pytest_collection_finish(session: pytest.Session) -> None:
    """Move everything collection made (the test modules, their items, the package's modules: ~170 000 objects)
    into the garbage collector's permanent generation. Every closed-loop run starts with a full `gc.collect()`
    (the runner's loop, so that no collection pauses it) and Python's own full collections come every so often:
    each walked that whole heap, 0.22 CPU-s in a worker, for objects that live until the session ends anyway.
    Objects the tests make are collected as before."""
    gc.collect()
    gc.freeze()


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Collect skips whose reason is not allowed in CI."""
    if os.environ.get("HIL_CI") != "1" or not report.skipped or hasattr(report, "wasxfail"):
        return
    reason = str(report.longrepr[2]) if isinstance(report.longrepr, tuple) else str(report.longrepr)
    # inside .ci/vcan-vm (VCAN_VM=1) vcan0 is up: a SocketCAN skip there is a failure
    in_vm = os.environ.get("VCAN_VM") == "1"
    allowed_skips = [a for a in CI_ALLOWED_SKIPS if not (in_vm and a == "no SocketCAN interface")]
    if not any(allowed in reason for allowed in allowed_skips):
        _unexpected.append(f"{report.nodeid}: {reason}")


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Fail the CI session on unexpected skips (listed)."""
    if _unexpected:
        print("\nunexpected skips in CI (install what they need in .ci/run):\n  " + "\n  ".join(_unexpected))
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


@pytest.fixture
def target_without_heartbeats(monkeypatch: pytest.MonkeyPatch) -> None:
    """The Python sim target sends every frame but its HeartbeatTargets: it never confirms a safe stop."""
    from pmsm_hil.sim_target.target import SimTarget

    real = SimTarget._send

    def without_heartbeats(self: SimTarget, msg: Any) -> None:
        if type(msg).__name__ != "Heartbeat":
            real(self, msg)

    monkeypatch.setattr(SimTarget, "_send", without_heartbeats)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object:
    """`--dist loadfile` (pyproject.toml's addopts): xdist's loadfile, longest units first and the files sharing a
    session fixture on one worker (tests/xdist_scheduling.py). Other `--dist` modes: xdist's own."""
    if config.getvalue("dist") != "loadfile":
        return None
    from tests.xdist_scheduling import CostOrderedFileScheduling

    return CostOrderedFileScheduling(config, log)  # type: ignore[arg-type]


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """`-n auto` (pyproject.toml's addopts): one worker per CPU and one more. The suite's tests wait for what they
    start (QEMU, SIL and spawned targets, `hil` and pytest processes, the contract tests' deliberate timeouts), so
    two workers on two cores kept them busy only ≈ 83 % of the wall time at load ≤ 2 (docs/ci.md). xdist's
    PYTEST_XDIST_AUTO_NUM_WORKERS still decides when set."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None
    return (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1) + 1


#: the pid of the pytest process that saw HIL_CPU_REPORT first: it and its xdist workers write the report
_CPU_REPORT_OWNER = "HIL_CPU_REPORT_SESSION"


def _cpu_s() -> float:
    """CPU seconds of this process and of its children it has waited for (user + system), and of the processes a
    helper process reaped for it (tests/reaped_cpu.py)."""
    from tests import reaped_cpu

    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime + sum(reaped_cpu.CPU_S) + _fork_server_cpu_s()


def _fork_server_cpu_s() -> float:
    """CPU seconds of the MCAP loggers' fork server (pmsm_hil.hil.runlog.fork_server) and of the loggers it forked
    and reaped: they are not this process's waited-for children."""
    server = sys.modules.get("pmsm_hil.hil.runlog.fork_server")
    pid = server.pid() if server is not None else None
    if pid is None:
        return 0.0
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return sum(int(f) for f in fields[11:15]) / os.sysconf("SC_CLK_TCK")  # utime, stime, cutime, cstime


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Generator[None, object, object]:
    """With `HIL_CPU_REPORT=FILE`, append "CPU-s wall-s node-id" per test (setup, call and teardown; the CPU of the
    worker and of the processes it started and waited for): the suite's cost independent of the machine's load
    (docs/ci.md, "The project's own suite")."""
    path = os.environ.get("HIL_CPU_REPORT")
    owner = os.environ.get(_CPU_REPORT_OWNER)
    worker = "PYTEST_XDIST_WORKER" in os.environ and owner == str(os.getppid())
    if not path or not (owner == str(os.getpid()) or worker):
        return (yield)  # not asked, or a pytest session a test started (its CPU is that test's)
    import time

    cpu0, t0 = _cpu_s(), time.monotonic()
    try:
        return (yield)
    finally:
        with open(path, "a", encoding="utf-8") as f:
            f.write(f"{_cpu_s() - cpu0:.3f} {time.monotonic() - t0:.3f} {item.nodeid}\n")
