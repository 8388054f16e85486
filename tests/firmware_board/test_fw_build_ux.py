"""`hil fw build` says what broke: a missing hil_app_* is a build error naming it on both boards (the
SIL library links with --no-undefined), the first compiler error comes with its caret context, warnings are shown
(count and lines, also when the build was up to date), `--define NAME=VALUE` reaches the compiler, `--verbose`
shows the commands."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.sim_target import fw_cache
from pmsm_hil.sim_target.fw_build import ARTEFACT, FIRMWARE_DIR, FwBuildError, build_firmware, key_lines, parse_defines
from pmsm_hil.sim_target.fw_params import FirmwareParamError, firmware_params
from tests.firmware_board.conftest import ROOT, need

CASES = Path(__file__).with_name("fw_cases")
CPP_TEMPLATE = ROOT / "examples" / "my_firmware_cpp"


@pytest.mark.parametrize("board", ["host", "mps2-an386"])
def test_missing_step_is_named(board: str, capsys: pytest.CaptureFixture[str]) -> None:
    need(board)
    with pytest.raises(FwBuildError, match=r"undefined reference to `hil_app_step'"):
        build_firmware(board, CASES / "no_step")
    assert main(["fw", "build", "--board", board, "--src", str(CASES / "no_step")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hil: error: build of ") and "hil_app_step" in err and "Traceback" not in err


def test_first_error_has_its_caret(capsys: pytest.CaptureFixture[str]) -> None:
    need("host")
    assert main(["fw", "build", "--src", str(CASES / "syntax")]) == 2
    lines = capsys.readouterr().err.splitlines()
    at = next(i for i, ln in enumerate(lines) if "cases.c:" in ln and "error:" in ln)
    assert "(void)m;" in lines[at + 1] and "^" in lines[at + 2]


def test_warnings_are_shown(capsys: pytest.CaptureFixture[str]) -> None:
    need("host")
    for _ in range(2):  # the second build is up to date: its warnings are those of the build that compiled
        assert main(["fw", "build", "--src", str(CASES / "warns")]) == 0
        err = capsys.readouterr().err
        assert err.startswith("1 compiler warning:\n") and "unused variable" in err and "unused_in_step" in err


def test_a_partial_rebuild_keeps_the_warnings_of_the_files_not_recompiled(tmp_path: Path) -> None:
    from pmsm_hil.sim_target.fw_build import _remember_warnings

    warn = "/src/app.c:3:5: warning: unused variable 'x' [-Wunused-variable]"
    first = f"[ 50%] Building C object CMakeFiles/fw.dir/src/app.c.o\n{warn}\n[100%] Building C object " \
            "CMakeFiles/fw.dir/sdk/core.c.o\n"
    assert _remember_warnings(tmp_path, first) == (warn,)
    core_only = "[100%] Building C object CMakeFiles/fw.dir/sdk/core.c.o\n"  # another file changed
    assert _remember_warnings(tmp_path, core_only) == (warn,)
    assert _remember_warnings(tmp_path, "") == (warn,)  # up to date
    fixed = "[ 50%] Building C object CMakeFiles/fw.dir/src/app.c.o\n"  # app.c recompiled without the warning
    assert _remember_warnings(tmp_path, fixed) == ()


def test_define_changes_a_compiled_constant() -> None:
    need("host")
    plain = build_firmware("host", CPP_TEMPLATE).path
    tuned = build_firmware("host", CPP_TEMPLATE, defines=["MY_FW_BANDWIDTH=900.0f"]).path
    assert plain != tuned  # each variant its own build folder
    assert [p.default for p in firmware_params(plain)] == [1500.0]
    assert [p.default for p in firmware_params(tuned)] == [900.0]


def test_verbose_shows_the_commands(capsys: pytest.CaptureFixture[str]) -> None:
    need("host")
    # the reference firmware: --verbose runs CMake past the cache, in the build folder the reference's builds share
    # (`hil fw build --no-cache` of tests/cli_status, a first build of the `reference_sil` fixture): one compile of
    # the SDK for them all, where a folder of its own (the C++ template's: its other tests find it in the cache)
    # compiled it again (~3 CPU-s)
    assert main(["fw", "build", "--verbose"]) == 0
    err = capsys.readouterr().err
    assert "+ cmake -S" in err and "+ cmake --build" in err


def test_bad_defines_are_one_line() -> None:
    assert parse_defines(["A=1", "B", "C_2="]) == ("A=1", "B=1", "C_2=")
    for bad in ("1A=2", "A B=1", "=3", "A=x;y"):
        with pytest.raises(FwBuildError, match=r"^--define "):
            parse_defines([bad])


def test_key_lines_of_a_link_failure() -> None:
    out = ("[ 50%] Building C object x.o\n/usr/bin/ld: a.o: in function `f':\n"
           "core.c:(.text+0x1): undefined reference to `hil_app_step'\ncore.c:(.text+0x9): undefined reference to "
           "`hil_app_reset'\ncollect2: error: ld returned 1 exit status\ngmake[2]: *** Error 1\n")
    assert key_lines(out) == ["core.c:(.text+0x1): undefined reference to `hil_app_step'",
                              "core.c:(.text+0x9): undefined reference to `hil_app_reset'"]


def _built_artefact(case: str) -> Path:
    """The library of a refused build of fw_cases/`case`, as the content-keyed cache holds it (a prebuilt firmware
    with that table, as a run may be given one)."""
    src = (CASES / case).resolve()
    entry = fw_cache.entry_dir(src, "host", fw_cache.content_key(src, FIRMWARE_DIR, "host", (), mcu=False))
    lib = entry / ARTEFACT["host"]
    assert lib.is_file(), lib
    return lib


@pytest.mark.parametrize(("case", "message"), [
    ("bad_params", r"hil_app_params\[1\] 'offset': id 12 outside 128\.\.254"),
    ("bad_params_name", r"hil_app_params\[0\] 'gain_of_the_speed_filter': name is not NUL-terminated within its "
                        r"24 bytes"),
    ("bad_params_inf", r"hil_app_params\[1\] 'offset': min -inf is not a finite number"),
])
def test_a_malformed_parameter_table_is_refused(case: str, message: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    need("host")
    with pytest.raises(FwBuildError, match=message):  # at build time
        build_firmware("host", CASES / case)
    with pytest.raises(FwBuildError, match=message):  # and found in the cache: refused again
        build_firmware("host", CASES / case)
    assert main(["fw", "build", "--src", str(CASES / case)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hil: error: ") and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    lib = _built_artefact(case)  # and by a run given such a library built elsewhere
    with pytest.raises(FirmwareParamError, match=message):
        firmware_params(lib)
    assert main(["run", "--target", f"sil:{lib}", "--no-log"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hil: error: ") and len(err.strip().splitlines()) == 1


def test_a_fresh_build_refuses_the_table_too() -> None:
    """Past the cache (`use_cache=False`: CMake runs): the built library's table is refused as the cached one is."""
    need("host")
    with pytest.raises(FwBuildError, match=r"hil_app_params\[1\] 'offset': id 12 outside 128\.\.254"):
        build_firmware("host", CASES / "bad_params", use_cache=False)
