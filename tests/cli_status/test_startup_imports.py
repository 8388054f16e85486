"""What a process imports before it does its job: `hil --help`, a subcommand's `--help` and a usage error build a
parser only (no numpy, python-can, cantools, MCAP, plotting or the runner); the MCAP logger process imports the
writer's modules, not the reader's, the links' or the runner's. Checked by the modules a fresh interpreter holds
(`sys.modules`), not by timing: each of these imports costs ~0.05-0.35 CPU-s of every such process."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

#: third-party packages and package modules that only doing the job needs
HEAVY = ("numpy", "can", "cantools", "serial", "mcap", "matplotlib", "rerun", "unicorn", "fmpy", "cffi", "scipy",
         "labgrid", "pmsm_hil.hil.runner.run", "pmsm_hil.hil.runner.run_config", "pmsm_hil.hil.runner.loop",
         "pmsm_hil.hil.runlog.logger", "pmsm_hil.protocol.links.link")

_MAIN = """
import contextlib, io, json, sys
from pmsm_hil.app.cli.main import main
out = io.StringIO()
with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
    try:
        code = main({argv!r})
    except SystemExit as exc:
        code = exc.code
print(json.dumps({{"code": code, "modules": sorted(sys.modules), "out": out.getvalue()}}))
"""


def _loaded(heavy: tuple[str, ...], modules: list[str]) -> list[str]:
    """The names of `heavy` present in `modules` (a package counts with any of its submodules)."""
    return [h for h in heavy if any(m == h or m.startswith(h + ".") for m in modules)]


def _run_main(argv: list[str]) -> dict[str, object]:
    proc = subprocess.run([sys.executable, "-c", _MAIN.format(argv=argv)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    result: dict[str, object] = json.loads(proc.stdout.splitlines()[-1])
    return result


@pytest.mark.parametrize(("argv", "code", "says"), [
    (["--help"], 0, "hardware-in-the-loop"),
    (["run", "--help"], 0, "exit codes"),
    (["run", "--no-such-option"], 2, "unrecognized arguments: --no-such-option"),
    (["run", "--speed", "fast"], 2, "--speed"),
    (["nosuch"], 2, "invalid choice"),
    (["sweep", "--help"], 0, "sweep"),
    (["compare", "--help"], 0, "Presets:"),
    (["bench", "--help"], 0, "plant periods per second"),
    (["bench", "loop", "--help"], 0, "--cross-process"),
    (["bench", "realtime", "--help"], 0, "--links"),
    (["bench", "controllers", "--help"], 0, "controller"),
    (["mcap", "export", "--help"], 0, "candump"),
    (["mcap-repair", "--help"], 0, "IN.mcap"),
    (["plant", "fluxmap", "--help"], 0, "flux map"),
    (["link-budget", "--help"], 0, "link"),
    (["target", "--help"], 0, "target"),
])
def test_help_and_usage_errors_import_no_heavy_module(argv: list[str], code: int, says: str) -> None:
    result = _run_main(argv)
    assert result["code"] == code and says in str(result["out"]), result["out"]
    modules = result["modules"]
    assert isinstance(modules, list)
    assert _loaded(HEAVY, modules) == []


def test_the_mcap_export_formats_are_the_writers() -> None:
    from pmsm_hil.app.cli.mcap_export import FORMAT_NAMES
    from pmsm_hil.hil.runlog.can_log import FORMATS

    assert tuple(FORMATS) == FORMAT_NAMES


def test_the_logger_process_imports_the_writer_only() -> None:
    """The modules the spawned MCAP logger loads to find its entry point and its target (`_worker_entry`,
    `run_worker`): mcap's writer and the numpy-free encoders, not numpy (a long run's logger imports it later, once
    its writes have used `sink.PURE_CPU_S`), mcap's reader, python-can, the links, the runner or the record dtypes."""
    code = ("import json, sys\nimport pmsm_hil.hil.runlog.worker_client, pmsm_hil.hil.runlog.worker\n"
            "print(json.dumps(sorted(sys.modules)))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    modules = json.loads(proc.stdout)
    assert "mcap.writer" in modules and "pmsm_hil.hil.runlog.pure_writer" in modules  # what writing MCAP needs
    heavy = (*[h for h in HEAVY if h != "mcap"], "mcap.stream_reader", "pmsm_hil.hil.runlog.reader",
             "pmsm_hil.hil.runlog.repair", "pmsm_hil.hil.runner", "pmsm_hil.protocol.links",
             "multiprocessing.forkserver", "pmsm_hil.hil.records", "pmsm_hil.hil.runlog.cdr",
             "pmsm_hil.hil.runlog.encoding", "pmsm_hil.app", "importlib.metadata", "email")
    assert _loaded(heavy, modules) == []


_SHORT_RUN = """
import contextlib, io, json, sys
from pmsm_hil.app.cli.main import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(["run", "--duration", "0.005", "--settle", "0", "--no-log", "--quiet", "--json", sys.argv[1]])
print(json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""


def test_a_short_run_imports_neither_package_metadata_nor_the_fmu_reader(tmp_path: Path) -> None:
    """`hil run`'s own process: the package version without `importlib.metadata` (email, csv...: ≈ 0.08 CPU-s,
    `pmsm_hil.dist_version`), without --load-fmu no FMU description reader (zipfile's use, xml), without sensor
    noise no numpy.random (`SensorModel`'s generator is made at its first draw)."""
    proc = subprocess.run([sys.executable, "-c", _SHORT_RUN, str(tmp_path / "metrics.json")], capture_output=True,
                          text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.splitlines()[-1])
    assert result["code"] == 0
    assert _loaded(("importlib.metadata", "email", "xml", "pmsm_hil.hil.load_fmu.description",
                    "pmsm_hil.hil.load_fmu.checks", "numpy.random"), result["modules"]) == []
    assert json.loads((tmp_path / "metrics.json").read_text())["end_code"] == 0


_SCRIPT_LOGGER = """
import json, sys
from pathlib import Path
from pmsm_hil.hil.runlog.logger import RunLogger
with RunLogger(Path(sys.argv[1]), metadata={{}}) as lg:
    pass
from multiprocessing import resource_tracker
print(json.dumps({{**lg.final_stats, "parent_mcap": sorted(m for m in sys.modules if m.split(".")[0] == "mcap"),
                  "tracker": resource_tracker._resource_tracker._pid}}))
"""


def test_a_logger_started_from_a_script_does_not_run_the_script_again(tmp_path: Path) -> None:
    """A `hil`, `pytest` or user script without a `__main__` guard: the spawned logger does not run it again
    (multiprocessing's spawn would, for a target defined there: the CLI's or pytest's whole import, or here a
    second logger started from inside the first one's start). The script itself, which only starts the logger,
    imports none of mcap (the logger's writer is imported in the logger process: `WorkerTarget`) and starts no
    multiprocessing resource tracker (a process of its own)."""
    script = tmp_path / "script.py"
    script.write_text(_SCRIPT_LOGGER.format())
    proc = subprocess.run([sys.executable, str(script), str(tmp_path / "run.mcap")], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    stats = json.loads(proc.stdout.splitlines()[-1])
    assert stats["reason"] == "close" and stats["numpy"] is False and stats["parent_mcap"] == []
    assert stats["tracker"] is None  # no resource tracker process started for the logger (`_no_tracker_started`)


def test_the_lazy_package_names_still_import() -> None:
    """`pmsm_hil.protocol.links`, `pmsm_hil.hil.runlog`, `pmsm_hil.app.compare` and `hil run`'s module load their
    public names on first use; each name is the defining module's."""
    from pmsm_hil.app import compare
    from pmsm_hil.app.cli import run as run_cli
    from pmsm_hil.hil import runlog
    from pmsm_hil.hil.runlog.logger import RunLogger
    from pmsm_hil.hil.runner.run import run_closed_loop
    from pmsm_hil.protocol import links
    from pmsm_hil.protocol.links.link import open_link

    for package in (compare, runlog, links):
        for name in package.__all__:
            assert getattr(package, name) is not None, name
    assert links.open_link is open_link and runlog.RunLogger is RunLogger
    assert run_cli.run_closed_loop is run_closed_loop
    with pytest.raises(AttributeError):
        _ = links.no_such_name


_NO_PYTHON_CAN = """
import os, sys
class _NoPythonCan:
    def find_spec(self, name, path=None, target=None):
        if name == "can" or name.startswith("can."):
            with open(os.environ["NO_PYTHON_CAN_LOG"], "a") as log:
                log.write(f"{name} in {sys.argv}\\n")
            raise ImportError(f"python-can imported: {name}")
        return None
sys.meta_path.insert(0, _NoPythonCan())
"""

_UDP_RUN_AND_PTY = """
import json, os, sys, tty
from pmsm_hil.app.cli.main import main
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import open_link
from pmsm_hil.protocol.links.kernel_drops import link_kernel_drops
from pmsm_hil.protocol.links.wire_core import link_socket_drops
code = main(["run", "--duration", "0.005", "--settle", "0", "--link", "udp", "--target", "spawn", "--no-log",
             "--quiet", "--json", sys.argv[1]])
master, slave = os.openpty()
tty.setraw(master)
tty.setraw(slave)
with open_link(f"serial:fd:{master}", "host") as host, open_link(f"serial:fd:{slave}", "target") as target:
    host.send([Frame(0x101, b"pty", True)])
    got = target.recv(5.0)
    extras = {**link_socket_drops(host), **link_kernel_drops(host)}
print(json.dumps({"code": code, "got": got.data.hex() if got else None, "extras": extras,
                  "can": sorted(m for m in sys.modules if m == "can" or m.startswith("can."))}))
"""


def test_a_run_over_udp_and_a_pty_link_need_no_python_can(tmp_path: Path) -> None:
    """`hil run --link udp --target spawn` (the host, its spawned `hil target` and the logger) and a serial link's
    two ends run without python-can's package (≈ 0.3 CPU-s of every such process): an import of it is refused and
    logged in each of these processes."""
    (tmp_path / "sitecustomize.py").write_text(_NO_PYTHON_CAN)
    log = tmp_path / "python-can.log"
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "NO_PYTHON_CAN_LOG": str(log)}
    proc = subprocess.run([sys.executable, "-c", _UDP_RUN_AND_PTY, str(tmp_path / "metrics.json")], env=env,
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.splitlines()[-1])
    assert result == {"code": 0, "got": b"pty".hex(), "extras": {}, "can": []}
    assert not log.exists(), log.read_text()
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["link"]["frames_rx"] > 0 and "socket_drops" in metrics["link"]
