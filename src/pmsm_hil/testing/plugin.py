"""The pytest side: options `--hil-target`, `--hil-motor`, `--hil-controller`, `--hil-out` and the fixtures
`hil` (per test: `hil.run(...)`, failure plots recorded in the JUnit XML) and `hil_session` (session-wide, for
module-scoped runs). Loaded by every pytest run of an installation (entry point `pytest11`), so it imports
only pytest here; nothing happens unless a test uses a fixture."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from pmsm_hil.testing.report import Reporter
    from pmsm_hil.testing.runs import HilResult, HilSettings


def pytest_addoption(parser: pytest.Parser) -> None:
    """The plugin's command-line options (group `pmsm-hil`)."""
    group = parser.getgroup("pmsm-hil", "pmsm-hil firmware tests (pmsm_hil.testing)")
    group.addoption("--hil-target", default="inproc", metavar="KIND",
                    help="target of hil.run: inproc (default: the reference firmware in-process on a virtual bus), "
                         "spawn (a `hil target` process over UDP), sil:PATH, qemu:PATH.elf, stm32g4:PATH.elf (as "
                         "`hil run --target`), external:LINKSPEC (a board on that link, e.g. external:socketcan:can0)")
    group.addoption("--hil-motor", default=None, metavar="PRESET|FILE",
                    help="motor of hil.run (default: hil run's)")
    group.addoption("--hil-controller", default=None, metavar="NAME",
                    help="controller of hil.run unless a test names one (default: hil run's; a foreign "
                         "firmware: external)")
    group.addoption("--hil-board", default=None, metavar="NAME|FILE",
                    help="stm32g4 targets: the board description of hil.run (as `hil run --board`)")
    group.addoption("--hil-ts", default=None, type=float, metavar="S",
                    help="control period of hil.run unless a test names one [s] (as `hil run --ts`; an stm32g4 "
                         "target's is its firmware's PWM carrier period)")
    group.addoption("--hil-out", default=None, metavar="DIR",
                    help="folder for run logs and failure plots, one subfolder per test (default: pytest's "
                         "temporary folders)")


#: what `--hil-target` accepts
TARGET_FORMS = "inproc, spawn, sil:PATH, qemu:PATH.elf, stm32g4:PATH.elf or external:LINKSPEC"


def target_problem(target: str, base: Path) -> str | None:
    """Why `--hil-target` `target` cannot be run (one line), or None: an unknown kind, a sil:/qemu: PATH that is
    not a file (relative to `base`, pytest's invocation folder), external without a valid link spec."""
    kind, sep, rest = target.partition(":")
    if target in ("inproc", "spawn"):
        return None
    if kind in ("sil", "qemu", "stm32g4") and sep:
        if not rest.strip():
            return f"--hil-target {target}: {kind}: needs the firmware's path ({kind}:PATH)"
        path = Path(rest) if Path(rest).is_absolute() else base / rest
        return None if path.is_file() else f"--hil-target {target}: {path} is not a file"
    if kind == "external":
        if not (sep and rest.strip()):
            return "--hil-target external needs a link: external:LINKSPEC, e.g. external:socketcan:can0"
        from pmsm_hil.protocol.errors import LinkSpecError
        from pmsm_hil.protocol.links.spec import parse_spec

        try:
            parse_spec(rest)
        except LinkSpecError as exc:
            return f"--hil-target {target}: {exc}"
        return None
    return f"--hil-target {target!r}: not one of {TARGET_FORMS}"


#: the link of the labgrid place the session leased (`--lg-env`), as `external:LINKSPEC`
BENCH_TARGET = pytest.StashKey[str]()
#: the name of that place
BENCH_PLACE = pytest.StashKey[str]()
#: how long a run that ended 3 or 4 on a leased place waits for the board's heartbeat before the session ends [s]
BOARD_CHECK_S = 3.0


def lg_env_file(config: pytest.Config) -> str | None:
    """labgrid's `--lg-env` (or `LG_ENV`) when labgrid's pytest plugin is loaded, else None."""
    import os

    option = getattr(config, "option", None)
    if option is None or not hasattr(option, "lg_env"):
        return None
    return config.option.lg_env or os.environ.get("LG_ENV") or None


def _lease_bench(config: pytest.Config, env_file: str) -> None:
    """Lease the place of the labgrid environment `env_file` for the whole session (waiting for it while another
    session holds it), bring its board to ready and make its link the `hil` target; released when pytest ends
    (after the JUnit XML is written, so a queued session's report starts after this one's ends)."""
    import contextlib

    from pmsm_hil.bench.errors import BenchError
    from pmsm_hil.bench.session import env_places, open_bench

    path = config.invocation_params.dir / env_file
    places = env_places(path)
    if len(places) != 1:
        raise pytest.UsageError(f"--lg-env {env_file}: the hil plugin needs exactly one RemotePlace (found "
                                f"{places or 'none'})")
    stack = contextlib.ExitStack()
    config.add_cleanup(stack.close)
    coordinator = getattr(config.option, "lg_coordinator", None)
    try:
        bench = stack.enter_context(open_bench(places[0], coordinator=coordinator, env_file=path))
    except BenchError as exc:
        raise pytest.UsageError(str(exc)) from None
    config.stash[BENCH_TARGET] = f"external:{bench.link}"
    config.stash[BENCH_PLACE] = bench.place


def check_bench(config: pytest.Config, end_code: int | None) -> None:
    """After a run on a leased place that ended 3 or 4, or could not start (`end_code` None): a board that gives no
    heartbeat within `BOARD_CHECK_S` ends the session (pytest exit 3) naming the bench; the place is released as
    the session ends."""
    place = config.stash.get(BENCH_PLACE, None)
    if place is None or end_code not in (3, 4, None):
        return
    from pmsm_hil.bench.heartbeat import wait_heartbeat

    link = config.stash[BENCH_TARGET].removeprefix("external:")
    if wait_heartbeat(link, BOARD_CHECK_S) is None:
        pytest.exit(f"bench {place}: the board stopped answering (no heartbeat on {link} within {BOARD_CHECK_S:g} s "
                    f"after a run); place {place} released", returncode=3)


def pytest_configure(config: pytest.Config) -> None:
    """A `--hil-target` that cannot be run is a usage error of the session (one line, pytest exit 4), not a
    failure of every test that uses `hil`. With labgrid's `--lg-env` naming a place, the session leases it."""
    problem = target_problem(str(config.getoption("--hil-target")), config.invocation_params.dir)
    if problem is not None:
        raise pytest.UsageError(problem)
    env_file = lg_env_file(config)
    if env_file is not None and not hasattr(config, "workerinput"):
        _lease_bench(config, env_file)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """pytest-xdist's `-n auto` (this repository's addopts): no workers for an `external:` target, whose one board
    cannot take two tests' runs at once; other targets start one per run, xdist's own count holds."""
    one_board = str(config.getoption("--hil-target")).startswith("external") or lg_env_file(config) is not None
    return 0 if one_board else None


def _settings(config: pytest.Config) -> HilSettings:
    from pmsm_hil.testing.runs import HilSettings

    out = config.getoption("--hil-out")
    target = config.stash.get(BENCH_TARGET, None) or config.getoption("--hil-target")
    ts = config.getoption("--hil-ts")
    return HilSettings(target=target, motor=config.getoption("--hil-motor"),
                       controller=config.getoption("--hil-controller"), board=config.getoption("--hil-board"),
                       ts=ts,
                       out=None if out is None else (config.invocation_params.dir / out).resolve())


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_")[:120] or "test"


class HilSession:
    """The session's settings and run factory: `run(folder, **choices)` runs into a fresh folder below the
    session's output (`--hil-out`, else a pytest temporary folder)."""

    def __init__(self, settings: HilSettings, base: Path) -> None:
        self.settings = settings
        self.base = base

    def folder(self, name: str) -> Path:
        """A new, empty folder `name` (or `name-2`, ...) below the session's output."""
        path, n = self.base / _slug(name), 2
        while path.exists():
            path, n = self.base / f"{_slug(name)}-{n}", n + 1
        path.mkdir(parents=True)
        return path

    def run(self, folder: str | Path, *, reporter: Reporter | None = None, **choices: Any) -> HilResult:
        """One closed-loop run (choices as `hil.run`) logged into the new folder `folder`."""
        from pmsm_hil.testing.runs import execute

        return execute(self.settings, self.folder(str(folder)), choices, reporter)


@pytest.fixture(scope="session")
def hil_session(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> HilSession:
    """The session's target, motor, controller and output folder (for module-scoped runs)."""
    settings = _settings(request.config)
    base = settings.out if settings.out is not None else tmp_path_factory.mktemp("hil", numbered=True)
    return HilSession(settings, base)


class Hil:
    """The `hil` fixture: `run(...)` takes the choices of `hil run` as keyword arguments (`controller`,
    `scenario`, `speed`, `load`, `duration`, `settle`, `params={...}`, `sets={...}`, `faults=SPEC`, and any
    other option by its name, e.g. `ts=50e-6`, `tolerate=3`) and returns a `HilResult`. Runs log into
    `--hil-out`/<test>/run-N (else the test's tmp_path); failing assertions write their plots there."""

    def __init__(self, session: HilSession, out_dir: Path, reporter: Reporter,
                 config: pytest.Config | None = None) -> None:
        self.session = session
        self.config = config
        self.out_dir = out_dir
        self.reporter = reporter
        self._runs = 0

    @property
    def target(self) -> str:
        """`--hil-target` of the session."""
        return self.session.settings.target

    def run(self, **choices: Any) -> HilResult:
        """One closed-loop run against the session's target (see the class)."""
        from pmsm_hil.errors import HilError
        from pmsm_hil.testing.runs import execute

        self._runs += 1
        folder = self.out_dir / f"run-{self._runs}"
        while folder.exists():
            self._runs += 1
            folder = self.out_dir / f"run-{self._runs}"
        try:
            result = execute(self.session.settings, folder, choices, self.reporter)
        except HilError:
            if self.config is not None:
                check_bench(self.config, None)
            raise
        if self.config is not None:
            check_bench(self.config, result.end_code)
        return result


@pytest.fixture
def hil(request: pytest.FixtureRequest, hil_session: HilSession, tmp_path: Path) -> Iterator[Hil]:
    """Closed-loop runs against `--hil-target` for this test (see `Hil`)."""
    from pmsm_hil.testing.report import Reporter, pop_reporter, push_reporter

    settings = hil_session.settings
    out_dir = tmp_path if settings.out is None else settings.out / _slug(request.node.nodeid)
    reporter = Reporter(out_dir, lambda: request.getfixturevalue("record_property"))
    push_reporter(reporter)
    try:
        yield Hil(hil_session, out_dir, reporter, request.config)
    finally:
        pop_reporter(reporter)


__all__ = ["BENCH_PLACE", "BENCH_TARGET", "TARGET_FORMS", "Hil", "HilSession", "check_bench", "hil", "hil_session",
           "lg_env_file",
           "pytest_addoption", "pytest_configure", "target_problem"]
