"""The mechanical load as an FMU: a third-party FMU (a fan law with a first-order lag, built
here from C) loads in the C loop, FMI 2.0 and 3.0; at 1500 rpm the mean load torque equals its steady value;
the recorded load follows the FMU's lag from the recorded speed (speed at each period start, torque held); a
failing doStep ends the run with a clear reason and a complete log; bad FMUs and options are one-line errors."""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.app.cli.run import add_run_arguments, config_from_args
from pmsm_hil.app.sweep.configure import base_options, build_config
from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.load_fmu.spec import LoadFmuSpec
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runlog.reader import read_metadata, read_periods
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from tests.load_fmu.fan_fmu import K_DEFAULT, TAU_DEFAULT, build_fan_fmu, fan_steady_torque, rad_s

SPEED_RPM = 1500.0


def _config(fmu: Path, *, params: tuple[tuple[str, float], ...] = (), settle_s: float = 0.05,
            duration_s: float = 0.1, out_dir: Path | None = None, **names: str) -> RunConfig:
    scenario = load_scenario("steady").with_overrides(speed_rpm=SPEED_RPM, settle_s=settle_s, duration_s=duration_s)
    return RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=scenario, controller="mpcc", out_dir=out_dir,
                     load_fmu=LoadFmuSpec(fmu, params=params, **names))


@pytest.mark.parametrize("fmi", [2, 3])
def test_fan_at_1500_rpm_mean_load_is_the_steady_value(fan_fmus: dict[int, Path], fmi: int) -> None:
    """Started at its steady state (T0 = k·ω²: a bumpless start, the speed PI preset on the FMU's torque), the
    fan holds 1500 rpm and its mean load torque over the window is k·ω² within 1 %, in lockstep in the C loop."""
    steady = fan_steady_torque(K_DEFAULT, rad_s(SPEED_RPM))
    res = run_closed_loop(_config(fan_fmus[fmi], params=(("T0", steady),)))
    m = res.metrics
    assert m["end_code"] == 0 and m["loop"] == "native" and m["mode"] == "lockstep"
    assert abs(m["speed_mean_rpm"] - SPEED_RPM) / SPEED_RPM < 0.005
    assert abs(m["load_torque_mean_nm"] - steady) / steady < 0.01
    # the electromagnetic torque carries the load (plus the small viscous friction)
    assert abs(m["torque_mean_nm"] - steady) / steady < 0.02
    fmu = m["load_fmu"]
    token = "guid" if fmi == 2 else "instantiation_token"
    assert fmu["fmi_version"] == f"{fmi}.0" and fmu["model_name"] == "FanLoad" and fmu["model_identifier"] == "fan_load"
    assert fmu[token] == "{7d3c51f0-2a9e-4c55-9e0a-fan-load-test}" and fmu["path"] == str(fan_fmus[fmi].resolve())
    assert fmu["parameters"] == {"T0": steady} and m["load_nm"] is None
    assert fmu["steps"] == m["total_periods"] == 1500 and fmu["warnings"] == 0


def test_recorded_load_follows_the_lag_from_the_recorded_speed(fan_fmus: dict[int, Path], tmp_path: Path) -> None:
    """From T0 = 0 the FMU's torque rises with its lag: each period's recorded load torque is the FMU's state at
    the period start, the next one its exact first-order step over Ts with the speed sampled at that start —
    recomputed here from the log's speeds (an independent implementation of the fan model)."""
    k, tau = 3.0e-4, 0.01
    cfg = _config(fan_fmus[2], params=(("k", k), ("tau", tau)), settle_s=0.02, duration_s=0.03, out_dir=tmp_path)
    res = run_closed_loop(cfg)
    assert res.metrics["end_code"] == 0
    periods = read_periods(tmp_path / "run.mcap")
    assert json.loads(read_metadata(tmp_path / "run.mcap")["load_fmu"])["parameters"] == {"k": k, "tau": tau}
    load, w = np.asarray(periods["load_torque"]), np.asarray(periods["omega_m"])
    assert len(load) == 500 and load[0] == 0.0
    decay = math.exp(-cfg.ts_s / tau)
    ss = k * w[:-1] * np.abs(w[:-1])
    expected = ss + (load[:-1] - ss) * decay
    np.testing.assert_allclose(load[1:], expected, rtol=0, atol=1e-12)
    assert load[-1] > 0.9 * k * w[-1] ** 2  # five time constants in: near the steady value


def test_renamed_variables_and_parameters_from_the_cli(tmp_path: Path) -> None:
    """--load-fmu-map names other variables, --load-fmu-set sets parameters (FMI 3 here)."""
    def rename(xml: str) -> str:
        return xml.replace('name="speed"', 'name="w_shaft"').replace('name="torque"', 'name="T_load"')

    fmu = build_fan_fmu(tmp_path, 3, name="renamed", xml=rename)
    out = tmp_path / "run"
    argv = ["run", "--load-fmu", str(fmu), "--load-fmu-map", "speed=w_shaft,torque=T_load", "--load-fmu-set",
            "k=1e-4", "--load-fmu-set", f"T0={fan_steady_torque(1e-4, rad_s(1000.0))}", "--speed", "1000",
            "--settle", "0.02", "--duration", "0.03", "--out", str(out)]
    assert main(argv) == 0
    m = json.loads((out / "metrics.json").read_text(encoding="utf-8"))
    assert m["load_fmu"]["speed"] == "w_shaft" and m["load_fmu"]["torque"] == "T_load"
    steady = fan_steady_torque(1e-4, rad_s(1000.0))
    assert abs(m["load_torque_mean_nm"] - steady) / steady < 0.01


def test_a_failing_do_step_ends_the_run_with_the_fmu_message_and_a_complete_log(fan_fmus: dict[int, Path],
                                                                              tmp_path: Path) -> None:
    """fail_at = 0.05 s: the doStep of period 500 fails; the run ends there (exit 1), says which call failed and
    what the FMU logged, stops safely, and the log holds every period before."""
    res = run_closed_loop(_config(fan_fmus[2], params=(("fail_at", 0.05),), out_dir=tmp_path))
    m = res.metrics
    assert m["end_code"] == 1 and m["safe_state"] is True
    reason = m["end_reason"]
    assert "fmi2DoStep at t = 0.05 s returned fmi2Error" in reason and "fan blade jammed" in reason
    assert "\n" not in reason and m["load_fmu"]["steps"] == 500
    periods = read_periods(tmp_path / "run.mcap")
    assert len(periods) == m["total_periods"] == 500
    assert json.loads((tmp_path / "metrics.json").read_text(encoding="utf-8"))["end_code"] == 1


def _cli_config(argv: list[str]) -> RunConfig:
    p = argparse.ArgumentParser()
    add_run_arguments(p)
    p.add_argument("--out", type=Path)
    p.add_argument("--no-log", action="store_true", default=None)
    p.add_argument("--json", type=Path)
    p.add_argument("--overwrite", action="store_true", default=None)
    p.add_argument("--log-trace", action="store_true", default=None)
    return config_from_args(p.parse_args([*argv, "--no-log"]))


@pytest.mark.parametrize(("make", "argv", "expected"), [
    (None, ["--load-fmu", "/nonexistent/fan.fmu"], "--load-fmu /nonexistent/fan.fmu: no such file"),
    ("notzip", [], "not an FMU (not a zip archive)"),
    ("fmi1", [], "FMI version 1.0 (FMI 2.0 and 3.0 Co-Simulation are supported)"),
    ("nobinary", [], "no binary binaries/linux64/fan_load.so for this platform"),
    ("ok", ["--load-fmu-map", "speed=w_shaft"], "no variable 'w_shaft' for the speed input"),
    ("ok", ["--load-fmu-map", "torque=k"], "variable 'k' (torque) has causality 'parameter', needs 'output'"),
    ("ok", ["--load-fmu-set", "nope=1"], "--load-fmu-set nope: no such variable (parameters: T0, fail_at, k, tau)"),
    ("ok", ["--load-fmu-set", "speed=1"], "--load-fmu-set speed: causality 'input'"),
    ("ok", ["--load-fmu-set", "k=abc"], "--load-fmu-set k: value 'abc' is not a number"),
    ("ok", ["--load-fmu-map", "inertia=J"], "--load-fmu-map: unknown role 'inertia' (roles: speed, torque)"),
    ("ok", ["--load", "3"], "--load and --load-fmu: one load at a time"),
    ("ok", ["--loop", "python"], "--load-fmu: a load FMU runs in the C loop only"),
    ("ok", ["--scenario", "dyno-steady"], "a load FMU needs mechanics = \"inertia\""),
    (None, ["--load-fmu-set", "k=1"], "--load-fmu-set: only with --load-fmu PATH.fmu"),
])
def test_bad_fmus_and_options_are_one_line_errors(tmp_path: Path, make: str | None, argv: list[str],
                                                  expected: str) -> None:
    if make == "notzip":
        path = tmp_path / "fan.fmu"
        path.write_text("not a zip\n", encoding="utf-8")
    elif make == "fmi1":
        path = build_fan_fmu(tmp_path, 2, xml=lambda x: x.replace('fmiVersion="2.0"', 'fmiVersion="1.0"'))
    elif make is not None:
        path = build_fan_fmu(tmp_path, 2, binary=make != "nobinary")
    fmu = [] if make is None else ["--load-fmu", str(path)]
    with pytest.raises(HilError) as info:
        _cli_config([*fmu, *argv])
    assert expected in str(info.value) and "\n" not in str(info.value)


def test_cli_error_is_one_line_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--load-fmu", "/nonexistent/fan.fmu", "--no-log"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["hil: error: --load-fmu /nonexistent/fan.fmu: no such file"]


@pytest.mark.parametrize(("make", "argv", "expected"), [
    ("notzip", [], "not an FMU (not a zip archive)"),
    ("fmi1", [], "FMI version 1.0 (FMI 2.0 and 3.0 Co-Simulation are supported)"),
    ("ok", ["--load-fmu-map", "speed=w_shaft"], "no variable 'w_shaft' for the speed input"),
    ("junkbinary", [], "cannot open its binary"),
])
def test_a_bad_fmu_file_is_one_line_exit_2_without_outputs(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                           make: str, argv: list[str], expected: str) -> None:
    """A bad FMU file (not an FMU, another FMI version, a variable it lacks, a binary that is not a shared
    library) is the user's input error, not a safety stop: `hil run` exits 2 with one line naming it, and writes
    no metrics.json (the contained crash tests: tests/load_fmu/test_containment.py)."""
    path = tmp_path / "fan.fmu"
    if make == "notzip":
        path.write_text("not a zip\n", encoding="utf-8")
    elif make == "fmi1":
        path = build_fan_fmu(tmp_path, 2, xml=lambda x: x.replace('fmiVersion="2.0"', 'fmiVersion="1.0"'))
    else:
        path = build_fan_fmu(tmp_path, 2)
    if make == "junkbinary":  # the same archive, its binary replaced by text
        import zipfile

        junk = tmp_path / "junk.fmu"
        with zipfile.ZipFile(path) as src, zipfile.ZipFile(junk, "w") as dst:
            for item in src.infolist():
                data = src.read(item)
                dst.writestr(item, b"not an ELF file\n" if item.filename.endswith(".so") else data)
        path = junk
    out = tmp_path / "run"
    assert main(["run", "--load-fmu", str(path), *argv, "--settle", "0", "--duration", "0.01", "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("hil: error: ") and expected in err[0], err
    assert not (out / "metrics.json").exists()


def test_a_sweep_varies_the_fmu_and_its_parameters(fan_fmus: dict[int, Path], tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """`load_fmu` and `load_fmu_set.NAME` are sweep keys; the base options stay untouched by a point."""
    from pmsm_hil.app.sweep import report

    reported: list[list[dict[str, Any]]] = []

    def write_html(path: Path, rows: list[dict[str, Any]], *args: Any, **kw: Any) -> Path:
        """The report's rows, kept (its matplotlib figure, ≈ 3.5 of this test's 4.6 CPU-s, is tests/sweep's)."""
        reported.append(rows)
        return path

    monkeypatch.setattr(report, "write_html", write_html)
    base = base_options({"load_fmu": str(fan_fmus[2]), "load_fmu_set": ["tau=0.01"]})
    cfg = build_config(base, (("load_fmu_set.k", "3e-4"),))
    assert cfg.load_fmu is not None and dict(cfg.load_fmu.params) == {"tau": 0.01, "k": 3e-4}
    assert base[0]["load_fmu_set"] == {"tau": "0.01"}
    other = build_config(base, (("load_fmu", str(fan_fmus[3])),))
    assert other.load_fmu_model is not None and other.load_fmu_model.fmi_version == 3
    out = tmp_path / "sweep"
    assert main(["sweep", "--grid", "load_fmu_set.k=1e-4,2e-4", "--load-fmu", str(fan_fmus[2]), "--speed", "1000",
                 "--duration", "0.03", "--settle", "0.03", "--workers", "0", "--quiet", "--out", str(out)]) == 0
    rows = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert sorted(r["load_fmu_set.k"] for r in rows) == [1e-4, 2e-4]
    low, high = sorted(rows, key=lambda r: r["load_fmu_set.k"])
    assert all(r["end_code"] == 0 for r in rows) and high["load_torque_mean_nm"] > low["load_torque_mean_nm"] > 0
    assert len(reported) == 1 and sorted(r["load_fmu_set.k"] for r in reported[0]) == [1e-4, 2e-4]


@pytest.mark.parametrize("fmi", [2, 3])
def test_builder_defaults_are_the_fmu_start_values(fan_fmus: dict[int, Path], fmi: int) -> None:
    """K_DEFAULT and TAU_DEFAULT (the steady values above use them) are the FMU's own start values."""
    from fmpy.model_description import read_model_description

    start = {v.name: v.start for v in read_model_description(str(fan_fmus[fmi])).modelVariables}
    assert float(start["k"]) == K_DEFAULT and float(start["tau"]) == TAU_DEFAULT


def test_replace_keeps_the_check(fan_fmus: dict[int, Path]) -> None:
    """A RunConfig copied with another load FMU is checked again (a bad copy is an error, not a late failure)."""
    cfg = _config(fan_fmus[2])
    with pytest.raises(HilError, match="no such file"):
        replace(cfg, load_fmu=LoadFmuSpec(Path("/nonexistent.fmu")))


#: the operating-range test's tolerances (tests/runner/test_operating_range.py)
SPEED_TOL_PCT, TORQUE_TOL_REL, TORQUE_TOL_MIN_NM = 1.0, 0.02, 0.05


@pytest.mark.parametrize(("speed_rpm", "k"), [(750.0, 4e-4), (750.0, 1e-3), (1500.0, 1e-4), (1500.0, 2.5e-4)])
def test_operating_range_with_a_fan_load(fan_fmus: dict[int, Path], speed_rpm: float, k: float) -> None:
    """The operating-range criteria with the FMU as the load (10-90 % of the niu2020's 7 N·m rated torque):
    speed within 1 % of the reference, electromagnetic torque within max(2 %, 0.05 N·m) of the load."""
    steady = fan_steady_torque(k, rad_s(speed_rpm))
    cfg = replace(_config(fan_fmus[2], params=(("k", k), ("T0", steady))),
                  scenario=load_scenario("steady").with_overrides(speed_rpm=speed_rpm, settle_s=0.05, duration_s=0.1))
    m = run_closed_loop(cfg).metrics
    assert m["end_code"] == 0
    assert abs(m["speed_mean_rpm"] - speed_rpm) / speed_rpm * 100.0 < SPEED_TOL_PCT
    load = m["load_torque_mean_nm"]
    assert abs(m["torque_mean_nm"] - load) < max(TORQUE_TOL_REL * load, TORQUE_TOL_MIN_NM)
    assert abs(load - steady) / steady < 0.01


@pytest.mark.timing
def test_the_c_loop_with_a_load_fmu_runs_at_least_50k_periods_per_second(fan_fmus: dict[int, Path]) -> None:
    """Lockstep, in-process target, logging off: the C loop's own rate (periods over the loop thread's wall time,
    set-up and safe stop left out), median of 3 runs of 0.5 s, with the FMU in its own process (the contained
    default: a shared-memory mailbox each period, its request sent before the target's step so that the two
    overlap) and in the run's process (unprotected): >= 50 000 periods/s both. `hil bench loop --load-fmu`
    prints both rates and their ratio in one run (docs/benchmarks.md)."""
    rates: dict[str, float] = {}
    for isolation in ("none", "process"):
        spec = replace(_config(fan_fmus[2]).load_fmu, isolation=isolation)  # type: ignore[type-var]
        cfg = replace(_config(fan_fmus[2], settle_s=0.0, duration_s=0.5), load_fmu=spec)
        runs = []
        for _ in range(3):
            res = run_closed_loop(cfg)
            assert res.metrics["end_code"] == 0
            runs.append(res.outcome.completed_periods / res.outcome.paced_time_s)
        rates[isolation] = sorted(runs)[1]
    assert rates["none"] >= 50_000.0, rates
    assert rates["process"] >= 50_000.0, rates


def test_an_fmu_that_refuses_to_instantiate_is_a_one_line_error(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    """A guid the binary does not know: fmi2Instantiate returns NULL; `hil run` says so in one line (exit 2)."""
    fmu = build_fan_fmu(tmp_path, 2, xml=lambda x: x.replace("fan-load-test}", "other-build}"))
    assert main(["run", "--load-fmu", str(fmu), "--no-log", "--duration", "0.01", "--settle", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "load FMU 'FanLoad'" in err[0] and "fmi2Instantiate at t = 0 s returned NULL" in err[0]


def test_a_cached_fan_fmu_is_the_one_its_inputs_ask_for(tmp_path: Path) -> None:
    """tests/load_fmu/fan_fmu.py's cache: the key changes with each input of the build, and a copy holds the model
    description asked for (two variants that differ only there are two entries)."""
    import zipfile

    from tests.load_fmu.fan_fmu import SRC, fmu_cache_key

    xml = (SRC / "modelDescription_fmi2.xml").read_text(encoding="utf-8")
    defines = {"LOAD_FMI": 2, "FAN_BAD": 0, "FAN_BAD_IN_INIT": 0}
    keys = {fmu_cache_key(2, xml, defines, True), fmu_cache_key(3, xml, defines, True),
            fmu_cache_key(2, xml + " ", defines, True), fmu_cache_key(2, xml, {**defines, "FAN_BAD": 1}, True),
            fmu_cache_key(2, xml, defines, False)}
    assert len(keys) == 5
    for tag in ("a", "b"):
        fmu = build_fan_fmu(tmp_path / tag, 2, xml=lambda x, tag=tag: x.replace("fan law", f"fan law {tag}"))
        with zipfile.ZipFile(fmu) as zf:
            assert f"fan law {tag}" in zf.read("modelDescription.xml").decode()
