"""`hil compare`: presets load, a short preset runs closed loop and writes table, JSON, CSV and PNG."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.app.compare import load_preset, preset_names, run_preset
from pmsm_hil.hil.errors import ParameterError
from tests.compare._presets import assert_rejected, preset_file


def test_bundled_presets_load() -> None:
    names = preset_names()
    assert {"niu2020-steady", "niu2020-accel", "niu2020-thd-vs-load", "niu2020-ripple-vs-speed"} <= set(names)
    assert {"xiao2023-steady", "xiao2023-tthr-sweep", "xiao2023-load-steps", "xiao2023-speed-step"} <= set(names)
    for name in names:
        p = load_preset(name)
        assert p.specs() and p.motor in ("niu2020-ipmsm", "xiao2023-spmsm", "zhang2021-dtpmsm")
    assert load_preset("niu2020-thd-vs-load").sweep_values[-1] == 7.0


def test_bad_presets_name_the_key(tmp_path: Path) -> None:
    with pytest.raises(ParameterError, match="unknown compare preset"):
        load_preset("nope")
    assert_rejected(tmp_path, 'name = "x"\nmotor = "niu2020-ipmsm"\nscenario = "steady"\ncontrollers = []\n',
                    "controllers")
    assert_rejected(tmp_path, 'name = "x"\nmotor = "m"\nscenario = "s"\ncontrollers = ["mpcc"]\nfigure = "pie"\n',
                    "figure")


def _short_preset(tmp_path: Path) -> Path:
    return preset_file(
        tmp_path,
        'name = "short"\nmotor = "niu2020-ipmsm"\nscenario = "steady"\ncontrollers = ["mpcc", "dsvm-20"]\n'
        'settle_s = 0.04\nduration_s = 0.04\nfigure = "bars"\n'
        'equal_fav = { reference = "dsvm-20", adjust = "mpcc" }\n'
        '[paper]\n"mpcc" = { torque_ripple_nm = 0.58 }\n', "short.toml")


def test_equal_fav_search_matches_switching_frequency(tmp_path: Path) -> None:
    res = run_preset(load_preset(str(_short_preset(tmp_path))))
    eq = [r for r in res.rows if r["group"] == "equal_fav"]
    assert len(eq) == 1 and eq[0]["controller"] == "mpcc"
    assert eq[0]["ts_us"] < 100.0
    assert eq[0]["switching_freq_khz"] == pytest.approx(eq[0]["equal_fav_target_khz"], rel=0.06)


def test_cli_writes_outputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    rc = main(["compare", "--preset", str(_short_preset(tmp_path)), "--out", str(out), "--quiet",
               "--controllers", "mpcc,dsvm-20"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "dsvm-20" in text and "torque_ripple_nm 0.58" in text
    data = json.loads((out / "short.json").read_text(encoding="utf-8"))
    assert {r["controller"] for r in data["rows"]} == {"mpcc", "dsvm-20"}
    with (out / "short.csv").open(encoding="utf-8") as fh:
        assert len(list(csv.DictReader(fh))) == len(data["rows"])
    assert (out / "short.png").read_bytes()[:4] == b"\x89PNG"


def test_cli_rejects_unknown_controller(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["compare", "--preset", "niu2020-steady", "--out", str(tmp_path), "--controllers", "nope"])
    assert rc == 2
    assert "unknown controller" in capsys.readouterr().err
