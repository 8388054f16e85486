"""`hil fw build -o` onto a path it cannot write: one line naming -o, exit 2, no traceback."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.sim_target.fw_build import FwBuildError, _copy_out
from tests.firmware_board.conftest import need


def test_unwritable_output_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    need("host")
    assert main(["fw", "build", "-o", "/proc/x.so"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hil: error: -o /proc/x.so: cannot write the libhil_firmware.so there (")
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_copy_out_errors_name_the_option(tmp_path: Path) -> None:
    artefact = tmp_path / "a.so"
    artefact.write_bytes(b"\x7fELF")
    (tmp_path / "file").write_text("x")
    with pytest.raises(FwBuildError, match=r"^-o .*file/sub/x\.so: cannot write"):
        _copy_out(artefact, tmp_path / "file" / "sub" / "x.so", "host")  # a file where a folder should be
    assert _copy_out(artefact, tmp_path / "out", "host") == tmp_path / "out"  # a new file named out
    (tmp_path / "d").mkdir()
    assert _copy_out(artefact, tmp_path / "d", "host").read_bytes() == b"\x7fELF"  # a folder: the artefact's name
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == ["libhil_firmware.so"]  # no temporary left
