"""The template user firmware (examples/my_firmware: its own FOC, PI current loops and five-segment SVPWM sent
as mirrored commands) builds for both boards and holds the rated point as controller `external`."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from tests.firmware_board._runs import assert_holds_rated, metrics, rated


def test_template_sil(template_sil: Path) -> None:
    assert_holds_rated(metrics(rated(f"sil:{template_sil}", controller="external")))


def test_template_qemu(template_elf: Path) -> None:
    m = metrics(rated(f"qemu:{template_elf}", controller="external", settle_s=0.03, duration_s=0.07))
    assert_holds_rated(m)
    assert m["exec_instructions"]["median"] > 100  # type: ignore[index]


def test_fw_build_cli_prints_sizes(template_elf: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = Path(__file__).resolve().parents[2] / "examples" / "my_firmware"
    assert main(["fw", "build", "--board", "mps2-an386", "--src", str(src), "-o", str(tmp_path / "fw.elf")]) == 0
    out = capsys.readouterr().out
    assert "text" in out and "bss" in out and (tmp_path / "fw.elf").is_file()
    assert main(["fw", "build", "--src", str(tmp_path)]) == 2  # no CMakeLists.txt: one-line error


def test_bench_controllers_mcu_prints_all_twelve(reference_elf: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from pmsm_hil.sim_target.firmware import CONTROLLERS

    assert main(["bench", "controllers", "--board", "mps2-an386", "--mcu-steps", "10", "--json",
                 str(tmp_path / "b.json")]) == 0
    out = capsys.readouterr().out
    names = [c.name for c in CONTROLLERS if c.id >= 1 and c.implemented]
    assert len(names) == 12
    for name in names:
        assert f" {name} " in out
    assert "ESTIMATE" in out and "55.83" in out  # beside the paper's Table 4
    payload = json.loads((tmp_path / "b.json").read_text())
    assert all(c["instructions"]["median"] > 100 for c in payload["controllers"])
