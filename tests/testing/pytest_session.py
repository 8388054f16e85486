"""Run pytest in a subprocess (the plugin as a user gets it: the installed `pytest11` entry point) and read the
outcome of each test from its JUnit XML."""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from tests.testing.pytest_zygote import run_session

ROOT = Path(__file__).resolve().parents[2]


@dataclass
class Case:
    """One <testcase>: name, module (classname), outcome (passed, failed, error, skipped), failure message,
    properties."""

    name: str
    module: str
    outcome: str
    message: str = ""
    properties: list[tuple[str, str]] = field(default_factory=list)


@dataclass
class Session:
    rc: int
    output: str
    cases: dict[str, Case]

    def of(self, module: str) -> dict[str, Case]:
        """The cases of the test modules whose dotted name ends with `module`."""
        return {name: c for name, c in self.cases.items() if c.module.endswith(module)}

    def failed(self, module: str = "") -> list[str]:
        """Names of the cases (of `module`) that did not pass."""
        return [name for name, case in self.of(module).items() if case.outcome != "passed"]

    def outcomes(self, module: str = "") -> dict[str, str]:
        return {name: case.outcome for name, case in self.of(module).items()}


def run_pytest(args: Sequence[str], tmp_path: Path, *, timeout_s: float = 240.0,
               pass_fds: Sequence[int] = ()) -> Session:
    """`python -m pytest ARGS --junitxml` from the repository root (HIL_CI unset: the inner session is a user's), in
    one process (`-n 0`: the repository's addopts ask for pytest-xdist workers), forked from the worker's pytest
    zygote (tests/testing/pytest_zygote.py: a process of its own without the interpreter's start-up); a session
    given file descriptors (`pass_fds`) is started as a new `python -m pytest` process."""
    n = len(list(tmp_path.glob('junit-*.xml')))
    junit = tmp_path / f"junit-{n}.xml"
    env = {k: v for k, v in os.environ.items() if k not in ("HIL_CI", "PYTEST_ADDOPTS")}
    argv = ["-p", "no:cacheprovider", "-q", "-n", "0", f"--junitxml={junit}", f"--basetemp={tmp_path / 'inner'}",
            *args]
    if pass_fds:
        proc = subprocess.run([sys.executable, "-m", "pytest", *argv], cwd=ROOT, env=env, capture_output=True,
                              text=True, timeout=timeout_s, pass_fds=tuple(pass_fds))
        rc, output = proc.returncode, proc.stdout + proc.stderr
    else:
        out, err = tmp_path / f"pytest-{n}.out", tmp_path / f"pytest-{n}.err"
        rc = run_session(argv, env, out, err, timeout_s)
        output = out.read_text(encoding="utf-8", errors="replace") + err.read_text(encoding="utf-8", errors="replace")
    cases: dict[str, Case] = {}
    if junit.exists():
        for tc in ET.parse(junit).getroot().iter("testcase"):
            outcome, message = "passed", ""
            for tag in ("failure", "error", "skipped"):
                node = tc.find(tag)
                if node is not None:
                    outcome, message = ("failed" if tag == "failure" else tag), node.get("message", "")
            props = [(p.get("name", ""), p.get("value", "")) for p in tc.iter("property")]
            name = tc.get("name", "")
            assert name not in cases, f"two tests named {name}: the checks key cases by name"
            cases[name] = Case(name, tc.get("classname", ""), outcome, message, props)
    return Session(rc, output, cases)
