"""The one-way dependency rule of docs/architecture.md ("Layers"): every import of a pmsm_hil module, at module
level or inside a function (lazy imports count), goes to its own layer or one it may use."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: repository folder -> import name (pyproject.toml [tool.setuptools] package-dir)
PACKAGES = {"src/pmsm_hil/hil": "pmsm_hil.hil", "src/pmsm_hil/app": "pmsm_hil.app",
            "src/pmsm_hil/protocol": "pmsm_hil.protocol", "src/pmsm_hil/sim_target": "pmsm_hil.sim_target",
            "src/pmsm_hil/dashboards": "pmsm_hil.dashboards", "src/pmsm_hil/testing": "pmsm_hil.testing",
            "src/pmsm_hil/conformance": "pmsm_hil.conformance"}

#: (module prefix, layer), most specific first
LAYER_OF = (
    ("pmsm_hil.errors", "base"),
    ("pmsm_hil.testing", "application"),
    ("pmsm_hil.conformance", "application"),
    ("pmsm_hil.protocol", "protocol"),
    ("pmsm_hil.sim_target", "target"),
    ("pmsm_hil.app", "application"),
    ("pmsm_hil.dashboards", "dashboards"),
    ("pmsm_hil.hil.runner", "runner"),
    ("pmsm_hil.hil.runlog", "infrastructure"),
    ("pmsm_hil.hil", "model"),
)
#: layer -> the layers it may import (besides itself)
MAY_USE = {
    "base": set(),
    "protocol": {"base"},
    "target": {"base", "protocol"},
    "model": {"base", "protocol"},
    "infrastructure": {"base", "model"},
    "runner": {"base", "protocol", "target", "model", "infrastructure"},
    "dashboards": {"base", "protocol", "model", "infrastructure", "runner"},
    "application": {"base", "protocol", "target", "model", "infrastructure", "runner", "dashboards"},
}


def layer(module: str) -> str:
    """Layer of a pmsm_hil module; ValueError for a module outside every layer."""
    for prefix, name in LAYER_OF:
        if module == prefix or module.startswith(prefix + "."):
            return name
    raise ValueError(f"{module}: no layer (add it to LAYER_OF and docs/architecture.md)")


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT)
    parts = list(rel.with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    for folder, package in PACKAGES.items():
        depth = len(Path(folder).parts)
        if tuple(parts[:depth]) == Path(folder).parts:
            return ".".join([package, *parts[depth:]])
    raise ValueError(f"{rel}: not below a package folder")


def imports(path: Path) -> Iterator[tuple[int, str]]:
    """(line, module) of every pmsm_hil import in the file, lazy ones included."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        for name in names:
            if name.startswith("pmsm_hil."):
                yield node.lineno, name


def violations(edges: list[tuple[str, int, str, str]]) -> list[str]:
    """Edges (file, line, importer, imported) against the rule, as messages."""
    out = []
    for file, line, src, dst in edges:
        a, b = layer(src), layer(dst)
        if a != b and b not in MAY_USE[a]:
            out.append(f"{file}:{line}: {src} ({a}) imports {dst} ({b}); {a} may use {sorted(MAY_USE[a])}")
    return out


def _edges() -> list[tuple[str, int, str, str]]:
    edges = []
    for folder in PACKAGES:
        for path in sorted((ROOT / folder).rglob("*.py")):
            src = module_name(path)
            for line, dst in imports(path):
                edges.append((str(path.relative_to(ROOT)), line, src, dst))
    return edges


def test_imports_follow_the_layer_rule() -> None:
    edges = _edges()
    assert len(edges) > 100  # the scan really saw the code
    assert violations(edges) == []


def test_the_rule_catches_an_upward_import() -> None:
    bad = [("src/pmsm_hil/sim_target/process.py", 9, "pmsm_hil.sim_target.process", "pmsm_hil.hil.runner.run_config"),
           ("src/pmsm_hil/hil/plant.py", 3, "pmsm_hil.hil.plant", "pmsm_hil.hil.runlog.logger"),
           ("src/pmsm_hil/hil/runlog/sink.py", 5, "pmsm_hil.hil.runlog.sink", "pmsm_hil.dashboards.live")]
    found = violations(bad)
    assert len(found) == 3 and "target" in found[0] and "model" in found[1]


def test_every_module_has_a_layer() -> None:
    for folder in PACKAGES:
        for path in (ROOT / folder).rglob("*.py"):
            layer(module_name(path))
    with pytest.raises(ValueError, match="no layer"):
        layer("pmsm_hil.elsewhere")


def test_the_exception_root_imports_nothing_and_every_layer_may_use_it() -> None:
    assert list(imports(ROOT / "src" / "pmsm_hil" / "errors.py")) == []
    assert all("base" in used for name, used in MAY_USE.items() if name != "base")


# --- the C side: plant kernels below the runner's loop (docs/architecture.md, "Machine kernels") -----------------
NATIVE = ROOT / "src" / "pmsm_hil" / "hil" / "runner" / "c"
#: the plant kernels and what they share, in their own folder: they know nothing of the loop, its links or the
#: firmware
KERNELS = ROOT / "src" / "pmsm_hil" / "hil" / "kernels"
KERNEL_FILES = {p.name for p in KERNELS.glob("*.[ch]")}
#: the only headers a kernel file may include
KERNEL_MAY_INCLUDE = {name for name in KERNEL_FILES if name.endswith(".h")}
#: kernel headers the loop may include: the interface, never a machine's own header
LOOP_MAY_INCLUDE_OF_KERNELS = {"machine_kernel.h", "gate_edges.h", "dq_segment.h"}


def c_includes(path: Path) -> list[tuple[int, str]]:
    """(line, header) of every `#include "..."` in a C file."""
    out = []
    for no, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        text = line.strip()
        if text.startswith("#include") and '"' in text:
            out.append((no, text.split('"')[1]))
    return out


def test_c_plant_kernels_include_only_kernel_headers() -> None:
    assert {"plant.c", "plant6.c", "machine_kernel.h"} <= KERNEL_FILES
    for name in sorted(KERNEL_FILES):
        for no, header in c_includes(KERNELS / name):
            assert header in KERNEL_MAY_INCLUDE, f"{KERNELS / name}:{no}: a plant kernel includes {header}"


def test_c_loop_reaches_the_plant_only_through_the_kernel_interface() -> None:
    loop_files = sorted(NATIVE.rglob("*.[ch]"))
    assert any(p.name == "loop.c" for p in loop_files)
    for path in loop_files:
        for no, header in c_includes(path):
            if header in KERNEL_FILES:
                assert header in LOOP_MAY_INCLUDE_OF_KERNELS, f"{path}:{no}: includes {header}"


def test_each_extension_compiles_its_own_layer() -> None:
    """The plant extension compiles the kernels and nothing of the loop; the loop extension no kernel (it calls
    the plant extension's through their tables)."""
    import importlib.util

    def builder(name: str) -> object:
        folder = KERNELS if name == "_build_plant" else NATIVE
        spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    plant_sources = set(builder("_build_plant").PLANT_SOURCES)  # type: ignore[attr-defined]
    assert plant_sources == {name for name in KERNEL_FILES if name.endswith(".c")}  # every kernel, from kernels/
    loop = builder("_build_loop")
    loop_sources = set(loop.LOOP_SOURCES) | set(loop.LINK_SOURCES)  # type: ignore[attr-defined]
    assert loop_sources and not (loop_sources & KERNEL_FILES)


def test_folders_are_layers() -> None:
    """The application lives in app/ (pmsm_hil.app), the model and runner in hil/: nothing under hil/ imports the
    dashboards or the application (no folder-level cycle)."""
    bad = [f"{file}:{line}: {dst}" for file, line, src, dst in _edges()
           if src.startswith("pmsm_hil.hil") and dst.startswith(("pmsm_hil.dashboards", "pmsm_hil.app"))]
    assert bad == []
