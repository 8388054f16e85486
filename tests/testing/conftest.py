"""Shared pytest subprocess sessions: one per target kind runs every user-side file at once (examples/ci, the user
files of user_project/, the conformance suite), so the interpreter, the plugin and the targets start once."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.testing.pytest_session import Session, run_pytest

USER = Path(__file__).with_name("user_project")
CONFORMANCE = "src/pmsm_hil/conformance"  # the package by its path; `--pyargs pmsm_hil.conformance` elsewhere


@pytest.fixture(scope="session")
def inproc_session(tmp_path_factory: pytest.TempPathFactory) -> tuple[Session, Path]:
    """examples/ci, user_checks.py, failing_assertion.py and the conformance suite on --hil-target inproc."""
    tmp = tmp_path_factory.mktemp("inproc")
    out = tmp / "hil-out"
    files = ["examples/ci", str(USER / "user_checks.py"), str(USER / "failing_assertion.py"), CONFORMANCE]
    return run_pytest([*files, "--hil-target", "inproc", "--hil-out", str(out)], tmp), out


@pytest.fixture(scope="session")
def spawn_session(tmp_path_factory: pytest.TempPathFactory) -> Session:
    """user_checks.py and the conformance suite on --hil-target spawn."""
    tmp = tmp_path_factory.mktemp("spawn")
    return run_pytest([str(USER / "user_checks.py"), CONFORMANCE, "--hil-target", "spawn"], tmp)
