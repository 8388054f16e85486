"""`pytest --pyargs pmsm_hil.conformance` passes against the reference firmware on every target kind (in-process,
spawned, an external `hil target` process on UDP) and against a foreign target written from the docs (on a pty
serial link), and fails naming the rule against a target that breaks one rule."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from pmsm_hil.conformance import RULES
from pmsm_hil.hil.runner.contract import RULES as CONTRACT_RULES
from pmsm_hil.protocol.links.wire_bus import free_udp_ports
from tests.testing.pytest_session import ROOT, Session, run_pytest

TARGET = Path(__file__).with_name("conformance_target.py")
#: the test ids of the suite, one per rule
TEST_IDS = {*(f"test_contract_rule[{r}]" for r in CONTRACT_RULES), "test_config_ack", "test_speed_mode",
            "test_safe_stop",
            *(f"test_probe_rule[{r}]" for r in RULES
              if r not in (*CONTRACT_RULES, "config_ack", "speed_mode", "safe_stop")),
            "test_every_rule_has_a_test"}


def _conformance(tmp_path: Path, *options: str, pass_fds: tuple[int, ...] = ()) -> Session:
    return run_pytest(["--pyargs", "pmsm_hil.conformance", *options], tmp_path, pass_fds=pass_fds)


def _all_passed(s: Session) -> None:
    assert s.rc == 0, s.output[-5000:]
    assert set(s.cases) == TEST_IDS and not s.failed(), {n: s.cases[n].message for n in s.failed()}


def test_the_reference_firmware_conforms_in_process_and_spawned(inproc_session: tuple[Session, Path],
                                                                spawn_session: Session) -> None:
    for s in (inproc_session[0], spawn_session):
        cases = s.of("test_conformance")
        assert set(cases) == TEST_IDS and not s.failed("test_conformance"), \
            {n: cases[n].message for n in s.failed("test_conformance")} or s.output[-4000:]


@contextlib.contextmanager
def _process(cmd: list[str], pass_fds: tuple[int, ...] = ()) -> Iterator[subprocess.Popen[str]]:
    """A target process, started and waited for (its `ready` line), stopped at the end."""
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            pass_fds=pass_fds)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith("ready"), line + proc.stdout.read()
        yield proc
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def test_an_external_hil_target_on_udp_conforms(tmp_path: Path) -> None:
    """A `hil target` process started here, the suite run with --hil-target external:udp:..."""
    host, target = free_udp_ports(2)
    cmd = [sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--link", f"udp:{target}:{host}",
           "--idle-timeout", "120"]
    with _process(cmd):
        _all_passed(_conformance(tmp_path, "--hil-target", f"external:udp:{host}:{target}"))


@pytest.fixture
def pty_pair() -> Iterator[tuple[int, str]]:
    """(master fd, slave path); the slave is kept open here so the master never sees a hang-up between the
    suite's connections (each opens the slave by its path)."""
    master, slave = os.openpty()
    yield master, os.ttyname(slave)
    for fd in (master, slave):
        with contextlib.suppress(OSError):
            os.close(fd)


def _breaking_target(tmp_path: Path, pty_pair: tuple[int, str], rule: str) -> Session:
    """The conformance suite against examples/python_target.py on a pty, breaking `rule` (`--break`)."""
    master, port = pty_pair
    with _process([sys.executable, str(TARGET), f"serial:fd:{master}", "--break", rule], pass_fds=(master,)):
        s = _conformance(tmp_path, "--hil-target", f"external:serial:{port}", "--hil-controller", "external")
    assert set(s.cases) == TEST_IDS, s.output[-3000:]
    return s


def test_a_foreign_target_breaking_one_rule_fails_that_rule_only(tmp_path: Path,
                                                                   pty_pair: tuple[int, str]) -> None:
    """examples/python_target.py's control law (+ the undefined-mode fault) on a pty, answering its 30th
    Measurement with durations 1 ns short: every test passes but `durations`, whose message names the rule."""
    s = _breaking_target(tmp_path, pty_pair, "durations")
    assert s.rc == 1 and s.failed() == ["test_contract_rule[durations]"], s.outcomes()
    message = s.cases["test_contract_rule[durations]"].message
    assert "conformance rule 'durations' broken" in message and "durations sum to 99999 ns" in message


def test_a_foreign_target_that_never_confirms_the_safe_stop_fails_that_rule_only(
        tmp_path: Path, pty_pair: tuple[int, str]) -> None:
    """The same target ignoring every disabling Setpoint's confirmation: only `safe_stop` fails, naming what the
    host saw."""
    s = _breaking_target(tmp_path, pty_pair, "safe_stop")
    assert s.rc == 1 and s.failed() == ["test_safe_stop"], s.outcomes()
    message = s.cases["test_safe_stop"].message
    assert "conformance rule 'safe_stop' broken" in message
    assert "no HeartbeatTarget in state idle within 500 ms of the disabling Setpoint" in message
