"""The content-keyed firmware build cache: the same sources in another folder build nothing (no CMake step), an
edited source, SDK file, define or outside header builds, a broken or partial entry is not used."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from pmsm_hil.sim_target import fw_cache
from pmsm_hil.sim_target.fw_build import FIRMWARE_DIR, build_firmware
from pmsm_hil.sim_target.fw_params import firmware_params
from tests.firmware_board.conftest import ROOT, need

CPP_TEMPLATE = ROOT / "examples" / "my_firmware_cpp"


def _build(src: Path, defines: tuple[str, ...] = ()) -> tuple[Path, list[str]]:
    """The artefact and the steps the build went through (`cached`, or `configuring`, `building`)."""
    steps: list[str] = []
    result = build_firmware("host", src, defines=defines,
                            progress=lambda step, _line: steps.append(step) if step not in steps else None)
    return result.path, steps


def test_the_same_sources_in_another_folder_build_nothing(tmp_path: Path) -> None:
    need("host")
    first, second = tmp_path / "clone-a" / "fw", tmp_path / "clone-b" / "fw"
    shutil.copytree(CPP_TEMPLATE, first)
    (first / "build").mkdir()  # a user's own build folder is not a source
    (first / "build" / "CMakeCache.txt").write_text("junk\n")
    shutil.copytree(CPP_TEMPLATE, second)
    built, _ = _build(first)
    again, steps = _build(second)
    assert steps == ["cached"]  # no cmake configure, no build
    assert again == built and again.is_file()
    assert [p.default for p in firmware_params(again)] == [1500.0]


def test_an_edited_source_builds_and_the_edit_is_in_the_firmware(tmp_path: Path) -> None:
    need("host")
    src = tmp_path / "fw"
    shutil.copytree(CPP_TEMPLATE, src)
    plain, _ = _build(src)
    app = src / "app.cpp"
    app.write_text(app.read_text(encoding="utf-8").replace("1500.0f", "1234.0f"), encoding="utf-8")
    edited, _ = _build(src)
    assert edited != plain
    assert [p.default for p in firmware_params(edited)] == [1234.0]
    assert [p.default for p in firmware_params(plain)] == [1500.0]  # the unedited entry is intact


def test_the_key_covers_the_sdk_the_board_the_defines_and_the_tools(tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    sdk = tmp_path / "sdk"
    shutil.copytree(FIRMWARE_DIR / "target", sdk / "target")
    base = fw_cache.content_key(CPP_TEMPLATE, sdk, "host", (), mcu=False)
    assert fw_cache.content_key(CPP_TEMPLATE, sdk, "host", (), mcu=False) == base
    assert fw_cache.content_key(CPP_TEMPLATE, sdk, "host", ("A=1",), mcu=False) != base
    assert fw_cache.content_key(CPP_TEMPLATE, sdk, "mps2-an386", (), mcu=True) != base
    core = next(p for p in sorted((sdk / "target").rglob("*.c")))
    core.write_text(core.read_text(encoding="utf-8") + "\n/* edited */\n", encoding="utf-8")
    assert fw_cache.content_key(CPP_TEMPLATE, sdk, "host", (), mcu=False) != base
    edited = fw_cache.content_key(CPP_TEMPLATE, sdk, "host", (), mcu=False)
    monkeypatch.setenv("CFLAGS", "-O0")
    assert fw_cache.content_key(CPP_TEMPLATE, sdk, "host", (), mcu=False) != edited


def test_an_entry_whose_outside_header_changed_or_that_is_partial_is_not_used(tmp_path: Path) -> None:
    header = tmp_path / "vendor" / "device.h"
    header.parent.mkdir()
    header.write_text("#define CLOCK_HZ 170000000\n")
    build = tmp_path / "build"
    (build / "CMakeFiles" / "fw.dir").mkdir(parents=True)
    (build / "CMakeFiles" / "fw.dir" / "app.c.o.d").write_text(
        f"CMakeFiles/fw.dir/app.c.o: {CPP_TEMPLATE / 'app.cpp'} \\\n {header} \\\n /usr/include/stdio.h\n")
    outside = fw_cache.outside_inputs(build, CPP_TEMPLATE, FIRMWARE_DIR)
    assert list(outside) == [str(header.resolve())]  # not the sources, not the system's headers
    artefact = tmp_path / "libhil_firmware.so"
    artefact.write_bytes(b"\x7fELF")
    entry = tmp_path / "cache" / "fw-host-k"
    stored = fw_cache.store(entry, artefact, (f"{CPP_TEMPLATE}/app.cpp:3: warning: x",), None, outside,
                            CPP_TEMPLATE, FIRMWARE_DIR)
    elsewhere = tmp_path / "copy"
    found = fw_cache.find(entry, artefact.name, elsewhere, FIRMWARE_DIR)
    assert found is not None and found.artefact == stored
    assert found.warnings == (f"{elsewhere}/app.cpp:3: warning: x",)  # the warning names this lookup's folder
    header.write_text("#define CLOCK_HZ 160000000\n")
    assert fw_cache.find(entry, artefact.name, CPP_TEMPLATE, FIRMWARE_DIR) is None
    header.write_text("#define CLOCK_HZ 170000000\n")
    stored.unlink()  # partial
    assert fw_cache.find(entry, artefact.name, CPP_TEMPLATE, FIRMWARE_DIR) is None
    (entry / "entry.json").write_text("{")
    assert fw_cache.find(entry, artefact.name, CPP_TEMPLATE, FIRMWARE_DIR) is None
