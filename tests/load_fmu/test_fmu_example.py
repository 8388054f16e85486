"""`hil fmu example DIR`: the documented example load FMU users start from, written and built with the host's C
compiler (the package's builder, the one the test suite's fan FMU uses), runs as `hil run --load-fmu` in FMI 2.0 and
3.0: each period's recorded load torque is the example's law at the speed recorded one period before (recomputed
here), its parameters set from the command line; `hil fmu build` rebuilds an edited folder; bad input is one line."""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.load_fmu.build import PLATFORM_DIR, FmuBuildError, build_fmu
from pmsm_hil.hil.runlog.reader import read_periods
from tests.load_fmu.fan_fmu import have_gcc

pytestmark = pytest.mark.skipif(not have_gcc(), reason="gcc not installed (needed to build the FMU)")


def steady(w: np.ndarray, t_coulomb: float, w_smooth: float, b_viscous: float, k_quadratic: float) -> np.ndarray:
    """The example's steady law, written again here: Coulomb (tanh-smoothed) + viscous + quadratic [N·m]."""
    return t_coulomb * np.tanh(w / w_smooth) + b_viscous * w + k_quadratic * w * np.abs(w)


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_example_builds_and_runs_as_the_load(fmi: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                 ) -> None:
    folder = tmp_path / "my_load"
    assert main(["fmu", "example", str(folder), "--fmi", str(fmi)]) == 0
    fmu = folder / "load_torque.fmu"
    assert fmu.is_file() and (folder / "load_torque.c").is_file() and (folder / "modelDescription.xml").is_file()
    assert str(fmu) in capsys.readouterr().out
    with zipfile.ZipFile(fmu) as zf:
        assert f"binaries/{PLATFORM_DIR[fmi]}/load_torque.so" in zf.namelist()
    out = tmp_path / "run"
    params = {"t_coulomb": 0.8, "b_viscous": 2e-3, "k_quadratic": 1.5e-4}
    argv = ["run", "--load-fmu", str(fmu), *(a for k, v in params.items() for a in ("--load-fmu-set", f"{k}={v}")),
            "--speed", "1000", "--settle", "0.02", "--duration", "0.03", "--out", str(out)]
    assert main(argv) == 0
    m = json.loads((out / "metrics.json").read_text(encoding="utf-8"))
    assert m["load_fmu"]["model_name"] == "LoadTorque" and m["load_fmu"]["fmi_version"] == f"{fmi}.0"
    assert m["load_fmu"]["parameters"] == params
    periods = read_periods(out / "run.mcap")
    load, w = np.asarray(periods["load_torque"]), np.asarray(periods["omega_m"])
    law = steady(w, params["t_coulomb"], 1.0, params["b_viscous"], params["k_quadratic"])
    # tau_lag = 0: the torque held over period k+1 is the law at the speed sampled at period k's start
    np.testing.assert_allclose(load[1:], law[:-1], rtol=0, atol=1e-12)
    assert load[0] == pytest.approx(law[0], abs=1e-12)  # started at its steady torque at the start speed
    w_mean = 1000.0 * 2 * math.pi / 60
    expected = float(steady(np.array([w_mean]), params["t_coulomb"], 1.0, params["b_viscous"],
                            params["k_quadratic"])[0])
    assert abs(m["load_torque_mean_nm"] - expected) / expected < 0.01


def test_an_edited_folder_is_rebuilt_by_fmu_build(tmp_path: Path) -> None:
    folder = tmp_path / "load"
    assert main(["fmu", "example", str(folder), "--fmi", "3"]) == 0
    fmu = folder / "load_torque.fmu"
    before = fmu.stat().st_mtime_ns
    src = folder / "load_torque.c"
    src.write_text(src.read_text(encoding="utf-8").replace("m->v[VR_T_COULOMB] = 0.5;", "m->v[VR_T_COULOMB] = 0.7;"),
                   encoding="utf-8")
    assert main(["fmu", "build", str(folder)]) == 0
    assert fmu.stat().st_mtime_ns >= before
    # the example refuses to overwrite the edited source without --overwrite
    with pytest.raises(FmuBuildError, match=r"load_torque\.c exists and differs from the example.*--overwrite"):
        main(["--debug", "fmu", "example", str(folder), "--fmi", "3"])
    assert main(["fmu", "example", str(folder), "--fmi", "3", "--overwrite"]) == 0


def test_build_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fmu", "build", str(tmp_path)]) == 2
    assert "modelDescription.xml: no model description" in capsys.readouterr().err
    assert main(["fmu", "example", str(tmp_path / "ok")]) == 0
    (tmp_path / "ok" / "load_torque.c").write_text("int broken(void) { return x; }\n", encoding="utf-8")
    assert main(["fmu", "build", str(tmp_path / "ok")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "failed" in err[0] and "error" in err[0], err
    with pytest.raises(FmuBuildError, match=r"fmiVersion '1\.0'"):
        build_fmu([], '<fmiModelDescription fmiVersion="1.0"/>', tmp_path / "x.fmu")
    with pytest.raises(FmuBuildError, match="modelIdentifier"):
        build_fmu([], '<fmiModelDescription fmiVersion="2.0"><CoSimulation modelIdentifier="a b"/>'
                      '</fmiModelDescription>', tmp_path / "x.fmu")


@pytest.mark.parametrize("fmi", [2, 3])
def test_fmpy_validates_and_simulates_the_example(fmi: int, tmp_path: Path) -> None:
    """Another importer than the runner: fmpy finds the model description valid, loads every FMI function (the
    stubs of fmi_unused.c) and simulates the law at a held speed."""
    from fmpy import simulate_fmu
    from fmpy.validation import validate_fmu

    assert main(["fmu", "example", str(tmp_path), "--fmi", str(fmi)]) == 0
    fmu = str(tmp_path / "load_torque.fmu")
    assert validate_fmu(fmu) == []
    result = simulate_fmu(fmu, stop_time=0.01, output_interval=1e-3, output=["torque"],
                          start_values={"speed": 100.0, "b_viscous": 2e-3})
    expected = float(steady(np.array([100.0]), 0.5, 1.0, 2e-3, 1e-4)[0])
    np.testing.assert_allclose(result["torque"], expected, rtol=0, atol=1e-12)
