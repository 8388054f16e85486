"""The one-way dependency rule of docs/architecture.md ("Layers"): folders are layers (src/pmsm_hil/FOLDER, the
table of the doc equals FOLDER_LAYERS), and every import of a pmsm_hil module, at module level or inside a function
(lazy imports count), goes to its own layer or one it may use. The C side alike: plant kernels, the runner's loop and
its links, each in its own folder."""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: the package: every folder below it is its import path (src/pmsm_hil/hil/runner/run.py is pmsm_hil.hil.runner.run)
PACKAGE = ROOT / "src" / "pmsm_hil"

#: folder (or module file) below src/pmsm_hil -> its layer; a module's layer is that of its longest listed folder
#: (docs/architecture.md "Layers": test_the_documented_layer_table_is_the_codes)
FOLDER_LAYERS = {
    "__init__.py": "base",
    "errors.py": "base",
    "lazy_names.py": "base",
    "dist_version.py": "base",
    "protocol": "protocol",
    "sim_target": "target",
    "hil": "model",
    "hil/runlog": "infrastructure",
    "hil/runner": "runner",
    "dashboards": "dashboards",
    "bench": "bench",
    "app": "application",
    "testing": "application",
    "conformance": "application",
}
#: layer -> the layers it may import (besides itself)
MAY_USE = {
    "base": set(),
    "protocol": {"base"},
    "target": {"base", "protocol"},
    "model": {"base", "protocol"},
    "infrastructure": {"base", "model"},
    "runner": {"base", "protocol", "target", "model", "infrastructure"},
    "dashboards": {"base", "protocol", "model", "infrastructure", "runner"},
    "bench": {"base", "protocol", "target", "model", "infrastructure", "runner"},
    "application": {"base", "protocol", "target", "model", "infrastructure", "runner", "dashboards", "bench"},
}
#: (module prefix, layer), most specific first: the folders as import names
LAYER_OF = tuple(sorted(((".".join(("pmsm_hil", *Path(folder).with_suffix("").parts)), name)
                         for folder, name in FOLDER_LAYERS.items()), key=lambda item: -len(item[0])))


def layer(module: str) -> str:
    """Layer of a pmsm_hil module; ValueError for a module outside every layer."""
    for prefix, name in LAYER_OF:
        if module == prefix or module.startswith(prefix + "."):
            return name
    if module == "pmsm_hil":
        return FOLDER_LAYERS["__init__.py"]
    raise ValueError(f"{module}: no layer (add its folder to FOLDER_LAYERS and docs/architecture.md)")


def module_name(path: Path) -> str:
    """The import name of a module file: its path below src/, dots for slashes (folder = import path)."""
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def modules() -> list[Path]:
    """Every Python file of the package."""
    return sorted(PACKAGE.rglob("*.py"))


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
    for path in modules():
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
    assert len(modules()) > 200
    for path in modules():
        layer(module_name(path))
    with pytest.raises(ValueError, match="no layer"):
        layer("pmsm_hil.elsewhere")


def test_every_listed_folder_exists() -> None:
    assert [f for f in FOLDER_LAYERS if not (PACKAGE / f).exists()] == []


def test_import_names_resolve_from_the_folders() -> None:
    """`import pmsm_hil.x` finds src/pmsm_hil/x: every package is its folder (no mapping, no symlink), and an
    import name found by the interpreter is the file at that path."""
    import importlib.util

    import pmsm_hil

    assert Path(pmsm_hil.__file__).resolve() == PACKAGE / "__init__.py"
    for path in modules():
        if path.parent.name in ("c", "kernels") or path.name.startswith("_build"):
            continue  # the cffi build scripts: run by setup.py, not imported
        spec = importlib.util.find_spec(module_name(path))
        assert spec is not None and spec.origin is not None, module_name(path)
        assert Path(spec.origin).resolve() == path.resolve(), module_name(path)


def test_the_exception_root_imports_nothing_and_every_layer_may_use_it() -> None:
    assert list(imports(PACKAGE / "errors.py")) == []
    assert all("base" in used for name, used in MAY_USE.items() if name != "base")


def _table_cells(line: str) -> list[str]:
    return [cell.strip() for cell in line.strip().strip("|").split("|")]


def documented_layers(text: str) -> tuple[dict[str, str], dict[str, set[str]]]:
    """docs/architecture.md's layer table: (folder -> layer, layer -> layers it may import). The folders of a row
    are its code-quoted names outside parentheses, without a trailing slash; "all of the above" names every layer of
    the rows above it."""
    lines = text.split("## Layers", 1)[1].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("| layer |"))
    folders: dict[str, str] = {}
    may: dict[str, set[str]] = {}
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        name, cell, uses = _table_cells(line)
        for folder in re.findall(r"`([^`]+)`", re.sub(r"\([^()]*\)", "", cell)):
            folders[folder.rstrip("/")] = name
        if uses == "all of the above":
            may[name] = set(may)
        else:
            may[name] = {u.strip() for u in uses.split(",") if u.strip() not in ("", "–", "-")}
    return folders, may


def test_the_documented_layer_table_is_the_codes() -> None:
    folders, may = documented_layers((ROOT / "docs" / "architecture.md").read_text(encoding="utf-8"))
    assert folders == FOLDER_LAYERS
    assert may == MAY_USE


def test_the_table_reader_sees_a_change() -> None:
    doc = ("## Layers\n\n| layer | folders | may import |\n|---|---|---|\n| base | `errors.py` (the root, `x/`) | – |\n"
           "| model | `hil/`, `hil/metrics/` (metrics) | base |\n| application | `app/` | all of the above |\n\nText.")
    folders, may = documented_layers(doc)
    assert folders == {"errors.py": "base", "hil": "model", "hil/metrics": "model", "app": "application"}
    assert may == {"base": set(), "model": {"base"}, "application": {"base", "model"}}


# --- the C side: plant kernels (model) below the runner's period loop and its links (docs/architecture.md) ---------
HIL = PACKAGE / "hil"
#: the plant kernels and what they share, in their own folder: they know nothing of the loop, its links or the
#: firmware
KERNELS = HIL / "kernels"
#: the runner's C: the period loop (and the native target's serve loop), beside the runner's Python
LOOP_C = HIL / "runner" / "c"
#: the C links the loop and the serve loop call through nl_link.h: UDP, serial, SocketCAN, the UDP floor
LINKS = LOOP_C / "links"
KERNEL_FILES = {p.name for p in KERNELS.glob("*.[ch]")}
LINK_FILES = {p.name for p in LINKS.glob("*.[ch]")}
#: the only headers a kernel file may include
KERNEL_MAY_INCLUDE = {name for name in KERNEL_FILES if name.endswith(".h")}
#: kernel headers the loop may include: the interface, never a machine's own header
LOOP_MAY_INCLUDE_OF_KERNELS = {"machine_kernel.h", "gate_edges.h", "dq_segment.h"}
#: what a link may include besides the link headers: the loop's clock and wait (loop_rt.h, which includes loop.h),
#: the target core's frame, authentication and serial framing (firmware_stub/target), the protocol's generated codec
#: (firmware_stub/generated: the virtual board's link decodes the Measurement and encodes the Command)
LINK_MAY_INCLUDE = {"loop_rt.h", "loop.h", "hil_target_core.h", "hil_auth.h", "hil_serial.h", "hil_protocol.h"}


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
    loop_files = sorted(LOOP_C.rglob("*.[ch]"))
    assert any(p.name == "loop.c" for p in loop_files) and any(p.name == "nl_link.c" for p in loop_files)
    for path in loop_files:
        for no, header in c_includes(path):
            if header in KERNEL_FILES:
                assert header in LOOP_MAY_INCLUDE_OF_KERNELS, f"{path}:{no}: includes {header}"


def test_c_links_know_only_the_link_interface_the_clock_and_the_target_framing() -> None:
    assert {"nl_link.h", "loop_udp.c", "loop_serial.c", "loop_socketcan.c"} <= LINK_FILES
    for name in sorted(LINK_FILES):
        for no, header in c_includes(LINKS / name):
            assert header in LINK_FILES | LINK_MAY_INCLUDE, f"{LINKS / name}:{no}: a link includes {header}"


def test_each_extension_compiles_its_own_folders() -> None:
    """The plant extension compiles the kernels (hil/kernels) and nothing of the loop; the loop extension compiles
    the loop (hil/runner/c) and the links (hil/runner/c/links), no kernel (it calls the plant extension's through
    their tables). The builders' source lists are read from their files (literal tuples): executing a builder runs
    the C preprocessor and cffi's parser over every header, seconds of CPU for three constants."""

    def sources(path: Path) -> dict[str, set[str]]:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        found = {}
        for node in tree.body:
            if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                    and node.targets[0].id.endswith("_SOURCES"):
                found[node.targets[0].id] = set(ast.literal_eval(node.value))
        compiled = [ast.unparse(k.value) for n in ast.walk(tree) if isinstance(n, ast.Call)
                    for k in n.keywords if k.arg == "sources"]  # set_source(..., sources=[...])
        assert len(compiled) == 1 and all(name in compiled[0] for name in found), (path, compiled)
        return found

    plant = sources(KERNELS / "_build_plant.py")
    assert plant == {"PLANT_SOURCES": {p.name for p in KERNELS.glob("*.c")}}
    loop = sources(LOOP_C / "_build_loop.py")
    assert loop == {"LOOP_SOURCES": {p.name for p in LOOP_C.glob("*.c")},
                    "LINK_SOURCES": {p.name for p in LINKS.glob("*.c")}}


def test_folders_are_layers() -> None:
    """The application lives in app/ (pmsm_hil.app), the model and runner in hil/: nothing under hil/ imports the
    dashboards or the application (no folder-level cycle)."""
    bad = [f"{file}:{line}: {dst}" for file, line, src, dst in _edges()
           if src.startswith("pmsm_hil.hil") and dst.startswith(("pmsm_hil.dashboards", "pmsm_hil.app"))]
    assert bad == []
