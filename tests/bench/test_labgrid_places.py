"""Two simulated benches behind a local labgrid coordinator and exporter (loopback, free ports): two pytest sessions
on one place queue (their JUnit suites do not overlap), on two places run at once, and `hil run --place` on a place
whose board stops answering ends with exit 3 naming the bench, the place released."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path

import pytest

pytest.importorskip("labgrid", reason="labgrid is not installed (the `bench` extra)")

from tests.bench.labgrid_benches import Benches

pytestmark = pytest.mark.slow

ENV = """\
targets:
  main:
    resources:
      RemotePlace: {{name: {place}}}
    drivers:
      - HilLinkDriver: {{}}
      - SimBoardDriver: {{}}
      - HilBenchStrategy: {{}}
options:
  coordinator_address: "{address}"
imports:
  - pmsm_hil.bench.labgrid_parts
"""

SESSION_TEST = """\
import time

def test_a_run_on_the_bench(hil):
    assert hil.target.startswith("external:udp:"), hil.target
    r = hil.run(duration=0.1, settle=0.02, lockstep_timeout=10, expect_hold=False)
    assert r.end_code == 0, r.end_reason
    time.sleep(2.0)  # the place stays held a while: sessions that overlap do so visibly
"""


@pytest.fixture(scope="module")
def benches(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Benches]:
    b = Benches(tmp_path_factory.mktemp("labgrid"), ("bench-a", "bench-b"))
    try:
        b.start()
        yield b
    finally:
        b.stop()


KILLED_BOARD_TEST = """\
import os
import signal
from pathlib import Path

def test_a_run_after_the_board_died(hil):
    me = os.getpid()
    kids = [int(c) for task in Path(f"/proc/{me}/task").iterdir() for c in (task / "children").read_text().split()]
    boards = [c for c in kids if b"target" in Path(f"/proc/{c}/cmdline").read_bytes().split(b"\\0")]
    assert len(boards) == 1, kids
    os.kill(boards[0], signal.SIGKILL)
    hil.run(duration=0.1, settle=0.02, lockstep_timeout=2, expect_hold=False)
    raise AssertionError("the session went on after its board stopped answering")
"""


def _session(benches: Benches, folder: Path, name: str, place: str,
             test: str = SESSION_TEST) -> subprocess.Popen[bytes]:
    """A pytest session on `place` under labgrid's plugin (`--lg-env`), its JUnit XML in folder/name.xml; without
    hypothesis's plugin (≈ 0.4 CPU-s a session, for tests that do not use it)."""
    env_file = folder / f"{name}.yaml"
    env_file.write_text(ENV.format(place=place, address=benches.address), encoding="utf-8")
    (folder / "test_bench_session.py").write_text(test, encoding="utf-8")
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:hypothesispytest", "-n", "0", "-q",
           "--lg-env", str(env_file),
           "--junitxml", str(folder / f"{name}.xml"), "--hil-out", str(folder / f"out-{name}"),
           str(folder / "test_bench_session.py")]
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "LG_"))}
    return subprocess.Popen(cmd, cwd=folder, env=env, stdout=(folder / f"{name}.log").open("wb"),
                            stderr=subprocess.STDOUT)


def _interval(xml: Path) -> tuple[float, float]:
    """[start, end] of the JUnit suite [s since the epoch]."""
    suite = ET.parse(xml).getroot()
    suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
    assert suite is not None
    start = datetime.fromisoformat(suite.attrib["timestamp"]).timestamp()
    return start, start + float(suite.attrib["time"])


@pytest.fixture(scope="module")
def sessions(benches: Benches, tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[float, float]]:
    """Three sessions started at once: a1 and a2 on bench-a, b1 on bench-b; each one's JUnit interval."""
    folder = tmp_path_factory.mktemp("sessions")
    procs = {name: _session(benches, folder, name, place)
             for name, place in (("a1", "bench-a"), ("a2", "bench-a"), ("b1", "bench-b"))}
    for name, proc in procs.items():
        assert proc.wait(600) == 0, (folder / f"{name}.log").read_text()
    return {name: _interval(folder / f"{name}.xml") for name in procs}


def _overlap(x: tuple[float, float], y: tuple[float, float]) -> float:
    return min(x[1], y[1]) - max(x[0], y[0])


def test_two_sessions_on_one_place_queue(sessions: dict[str, tuple[float, float]],
                                         benches: Benches) -> None:
    assert _overlap(sessions["a1"], sessions["a2"]) < 0, sessions
    assert benches.held() == [], "a place still held"


def test_sessions_on_two_places_overlap(sessions: dict[str, tuple[float, float]]) -> None:
    first = min(("a1", "a2"), key=lambda name: sessions[name][0])
    assert _overlap(sessions["b1"], sessions[first]) > 0.5, sessions


def _children(pid: int) -> list[int]:
    found: list[int] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        text = (task / "children").read_text().split()
        for child in map(int, text):
            found += [child, *_children(child)]
    return found


def _periods_logged(path: Path) -> bool:
    """Whether the run's log holds a period (its first chunk flushed): the host and the board agreed their session
    and periods flow. `run.mcap` alone exists before the handshake: a board killed then is met by the session's
    agreement ("no session agreed", exit 2), not by the run."""
    from pmsm_hil.hil.runlog import read_periods
    from pmsm_hil.hil.runlog.errors import McapFormatError

    try:
        return path.exists() and read_periods(path).shape[0] > 0
    except McapFormatError:  # its header not written yet
        return False


def test_a_board_that_stops_answering_ends_the_run_naming_the_bench(benches: Benches, tmp_path: Path) -> None:
    cmd = [sys.executable, "-m", "pmsm_hil.app.cli.main", "run", "--place", "bench-b", "--coordinator",
           benches.address, "--duration", "30", "--lockstep-timeout", "2", "--out", str(tmp_path / "run")]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    board = None
    deadline = time.monotonic() + 300
    while board is None and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.5)
        if _periods_logged(tmp_path / "run" / "run.mcap"):  # the run has started: the board agreed its session
            board = next((c for c in _children(proc.pid)
                          if b"target" in Path(f"/proc/{c}/cmdline").read_bytes().split(b"\0")), None)
    assert board is not None, proc.communicate()
    os.kill(board, signal.SIGKILL)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 3, (out, err)
    assert "bench bench-b" in err and "place bench-b released" in err, err
    assert benches.held() == [], "a place still held"


def test_a_session_whose_board_stops_answering_ends_naming_the_bench(benches: Benches, tmp_path: Path) -> None:
    proc = _session(benches, tmp_path, "dies", "bench-a", KILLED_BOARD_TEST)
    code = proc.wait(600)
    log = (tmp_path / "dies.log").read_text()
    assert code == 3, log
    assert "bench bench-a: the board stopped answering" in log and "place bench-a released" in log, log
    assert benches.held() == [], "a place still held"


def test_an_unknown_place_is_one_error_naming_it(benches: Benches, tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "pmsm_hil.app.cli.main", "run", "--place", "bench-c",
                           "--coordinator", benches.address, "--out", str(tmp_path / "run")],
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 2, done
    assert "bench bench-c: no such place on the coordinator" in done.stderr and "bench-a, bench-b" in done.stderr
