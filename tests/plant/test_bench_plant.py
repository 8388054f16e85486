"""`hil bench plant`: result structure and sanity of the figures (no timing thresholds)."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.app.bench.plant_bench import (
    PlantBenchResult,
    format_result,
    run_plant_bench,
    three_vector_commands,
)
from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.errors import ParameterError

PLANT_KEYS = ("periods_per_s_single", "periods_per_s_single_trace", "periods_per_s_three",
              "periods_per_s_three_trace", "periods_per_s_single_advance_only")
GEM_RATE_KEYS = ("gem_steps_per_s", "gem_steps_per_s_euler", "ratio_vs_gem", "ratio_vs_gem_trace",
                 "ratio_vs_gem_euler", "ratio_vs_gem_advance_only")
GEM_DI_KEYS = ("gem_max_abs_di_a", "gem_max_abs_di_abc_a", "gem_euler_max_abs_di_a")
#: looked up, not imported (GEM and matplotlib cost ≈ 1 CPU-s in every worker that collects this file)
needs_gem = pytest.mark.skipif(importlib.util.find_spec("gym_electric_motor") is None,
                               reason="gym-electric-motor not installed")


def _positive(d: dict[str, float | int | str | None], keys: tuple[str, ...]) -> None:
    for key in keys:
        value = d[key]
        assert isinstance(value, float) and math.isfinite(value) and value > 0, (key, value)


def test_plant_only_result_has_positive_rates_and_no_gem_figures() -> None:
    r = run_plant_bench(periods=30, repeats=2, accuracy_periods=10, include_gem=False)
    d = r.to_dict()
    _positive(d, PLANT_KEYS)
    assert (d["periods"], d["repeats"], d["motor"]) == (30, 2, "niu2020-ipmsm")
    assert all(d[k] is None for k in (*GEM_RATE_KEYS, *GEM_DI_KEYS, "gem_version"))
    assert any("not installed" in line or "skipped (--no-gem)" in line for line in format_result(r))


@needs_gem
def test_gem_comparison_figures_are_present_and_consistent() -> None:
    r = run_plant_bench(periods=30, repeats=1, accuracy_periods=50)
    d = r.to_dict()
    _positive(d, PLANT_KEYS + GEM_RATE_KEYS + GEM_DI_KEYS)
    assert r.ratio_vs_gem == pytest.approx(r.periods_per_s_single / (r.gem_steps_per_s or 1.0))
    # GEM freezes the inverter voltage in dq over each step: a real, sub-ampere deviation
    assert 1e-3 < (r.gem_max_abs_di_a or 0.0) < 2.0
    text = "\n".join(format_result(r))
    assert "simulate" in text and "ours/theirs" in text


def test_three_vector_commands_sum_to_ts() -> None:
    cmds = three_vector_commands(200, 100_000, np.random.default_rng(0))
    assert all(len(s) == 3 and sum(d) == 100_000 and min(d) >= 0 for s, d in cmds)
    assert all(0 <= x <= 7 for s, _ in cmds for x in s)


@pytest.mark.parametrize("field", ["periods", "repeats", "accuracy_periods"])
def test_bad_counts_are_rejected_by_name(field: str) -> None:
    kwargs = {"periods": 5, "repeats": 1, "accuracy_periods": 5, field: 0}
    with pytest.raises(ParameterError, match=field):
        run_plant_bench(include_gem=False, **kwargs)


def test_cli_prints_figures_and_writes_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "bench.json"
    rc = main(["bench", "plant", "--periods", "20", "--repeats", "1", "--accuracy-periods", "10",
               "--no-gem", "--json", str(out)])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "periods/s" in printed and str(out) in printed
    data = json.loads(out.read_text(encoding="utf-8"))
    assert set(data) == set(PlantBenchResult.__dataclass_fields__)
    _positive(data, PLANT_KEYS)


def test_cli_bad_periods_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["bench", "plant", "--periods", "0"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--periods" in err and "Traceback" not in err


def test_cli_unwritable_json_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["bench", "plant", "--periods", "5", "--repeats", "1", "--no-gem",
               "--json", str(tmp_path / "missing-dir" / "b.json")])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hil: error: --json") and "does not exist" in err and len(err.splitlines()) == 1
