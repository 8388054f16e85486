"""`hil compare` through the sweep engines: a preset gives the same rows (wall-clock fields aside) in this
process and on a local pool of 2 workers, equal-f_av search included; `hil bench sweep` prints its ratio."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.app.compare import load_preset, run_preset
from pmsm_hil.app.sweep.engines import LocalEngine
from tests.compare._presets import preset_file

SHORT_PRESET = ('name = "short"\nmotor = "niu2020-ipmsm"\nscenario = "steady"\ncontrollers = ["mpcc", "dsvm-20"]\n'
                'settle_s = 0.03\nduration_s = 0.03\nfigure = "thd_vs_load"\ntheta0_rad = [0.0, 1.0]\n'
                'sweep = { key = "load_nm", values = [3.0, 7.0] }\n'
                'equal_fav = { reference = "dsvm-20", adjust = "mpcc" }\n')


def _deterministic(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: v for k, v in r.items() if not k.startswith("exec_")} for r in rows]


def test_compare_rows_equal_on_a_pool(tmp_path: Path) -> None:
    preset = load_preset(str(preset_file(tmp_path, SHORT_PRESET)))
    inline = run_preset(preset)
    with LocalEngine(2) as engine:
        pooled = run_preset(preset, engine=engine)
    assert len(inline.rows) == len(pooled.rows) >= 10  # 2 controllers × 2 loads × 2 angles + equal f_av
    assert _deterministic(pooled.rows) == _deterministic(inline.rows)  # same order, same figures
    assert [r["group"] for r in pooled.rows].count("equal_fav") == 4  # 2 loads × 2 angles


def test_bench_sweep_prints_the_ratio(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "sweep", "--repeat", "1", "--sim", "0.02"]) == 0
    out = capsys.readouterr().out
    assert "ratio 2 workers / 1 worker: " in out and "load average before" in out
    assert "metrics identical on 1 and 2 workers: yes; runs that did not complete: 0" in out
    assert "cores busy during the 1-worker rounds: " in out and "--loop auto" in out
