"""One exception root: every exception class defined anywhere in the package derives from
`pmsm_hil.errors.HilError` (docs/architecture.md, "Exceptions"), keeping its built-in base."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from pathlib import Path
from types import ModuleType

import pytest

from pmsm_hil.errors import HilError

ROOT = Path(__file__).resolve().parent.parent
#: optional extras a module may need (pyproject.toml [project.optional-dependencies]); a module that cannot be
#: imported for any other reason fails the test
OPTIONAL = {"dask", "distributed", "ray", "gym_electric_motor", "gem", "rerun", "labgrid"}


def _packages() -> list[str]:
    """The package's root import name (src/pmsm_hil: every sub-package below it is walked)."""
    assert (ROOT / "src" / "pmsm_hil" / "__init__.py").is_file()
    return ["pmsm_hil"]


def _modules() -> tuple[list[ModuleType], list[str]]:
    """Every importable module of the package, and the names of those skipped for a missing optional extra."""
    found: dict[str, ModuleType] = {}
    skipped = []
    for package in _packages():
        pkg = importlib.import_module(package)
        found[package] = pkg
        for info in pkgutil.walk_packages(pkg.__path__, package + "."):
            if info.name in found:
                continue
            try:
                found[info.name] = importlib.import_module(info.name)
            except ModuleNotFoundError as exc:
                if (exc.name or "").split(".")[0] not in OPTIONAL:
                    raise
                skipped.append(info.name)
    return list(found.values()), skipped


def _exception_classes(modules: list[ModuleType]) -> dict[str, type[BaseException]]:
    """qualified name -> every BaseException subclass defined (not imported) in the modules, nested ones too."""
    out: dict[str, type[BaseException]] = {}

    def visit(owner: object, module: str) -> None:
        for _, obj in inspect.getmembers(owner, inspect.isclass):
            if obj.__module__ != module or f"{module}.{obj.__qualname__}" in out:
                continue
            if issubclass(obj, BaseException):
                out[f"{module}.{obj.__qualname__}"] = obj
            visit(obj, module)

    for mod in modules:
        visit(mod, mod.__name__)
    return out


def test_every_exception_class_derives_from_hil_error() -> None:
    modules, skipped = _modules()
    names = {m.__name__ for m in modules}
    assert {"pmsm_hil.app.cli.main", "pmsm_hil.protocol.codec", "pmsm_hil.sim_target.firmware",
            "pmsm_hil.dashboards.errors", "pmsm_hil.testing.signals", "pmsm_hil.hil.runlog.errors"} <= names
    assert len(modules) > 150, skipped  # the walk really saw the package
    classes = _exception_classes(modules)
    assert len(classes) >= 30  # the package's error classes were found
    outside = sorted(name for name, cls in classes.items() if not issubclass(cls, HilError))
    assert outside == []


@pytest.mark.parametrize(("name", "builtin"), [
    ("pmsm_hil.hil.errors.ParameterError", ValueError),
    ("pmsm_hil.protocol.errors.LinkSpecError", ValueError),
    ("pmsm_hil.hil.metrics.errors.MetricsError", ValueError),
    ("pmsm_hil.hil.runlog.errors.RunLogError", RuntimeError),
    ("pmsm_hil.sim_target.elf.ElfError", ValueError),
    ("pmsm_hil.testing.signals.SignalAssertionError", AssertionError),
    ("pmsm_hil.testing.runs.HilRunError", RuntimeError),
])
def test_built_in_bases_are_kept(name: str, builtin: type[Exception]) -> None:
    module, _, cls = name.rpartition(".")
    error = getattr(importlib.import_module(module), cls)
    assert issubclass(error, HilError) and issubclass(error, builtin)


def test_the_old_roots_are_the_one_root() -> None:
    from pmsm_hil.hil.errors import HilError as ModelRoot

    assert ModelRoot is HilError


@pytest.mark.parametrize("error", [
    importlib.import_module("pmsm_hil.protocol.links.wire_bus").UdpSessionError("hiludp: no session agreed"),
    importlib.import_module("pmsm_hil.hil.runlog.errors").McapFormatError("not an MCAP file"),
    importlib.import_module("pmsm_hil.sim_target.firmware").FirmwareConfigError("ld: value not finite"),
    importlib.import_module("pmsm_hil.hil.metrics.errors").MetricsWindowError("window empty"),
])
def test_cli_reports_any_hil_error_in_one_line_exit_2(error: HilError, monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    from pmsm_hil.app.cli import link_budget, main

    def fail(args: object) -> int:
        raise error

    monkeypatch.setattr(link_budget, "run", fail)
    assert main.main(["link-budget"]) == 2
    assert capsys.readouterr().err == f"hil: error: {error}\n"


def test_cli_other_endings_keep_their_codes(monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C is 130; an error outside the tree is a bug: it propagates (a traceback, exit 1)."""
    from pmsm_hil.app.cli import link_budget, main

    def interrupted(args: object) -> int:
        raise KeyboardInterrupt

    def bug(args: object) -> int:
        raise ZeroDivisionError("bug")

    monkeypatch.setattr(link_budget, "run", interrupted)
    assert main.main(["link-budget"]) == 130
    monkeypatch.setattr(link_budget, "run", bug)
    with pytest.raises(ZeroDivisionError):
        main.main(["link-budget"])
