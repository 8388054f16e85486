"""The induction machine closed loop: `hil run --motor im-2k2 --controller im-foc --speed 1000
--load 10` from zero flux holds the speed within 0.5 % and the mean torque within 1 % of the load; the C period
loop runs the kind through its kernel table with the Python loop's records bit for bit."""

from __future__ import annotations

import json
from pathlib import Path

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from tests.runner.loop_pairs import assert_bit_identical, reference_and_c_records


def test_hil_run_im_foc_holds_speed_and_torque(tmp_path: Path) -> None:
    out = tmp_path / "run"
    rc = main(["run", "--motor", "im-2k2", "--controller", "im-foc", "--speed", "1000", "--load", "10",
               "--out", str(out)])
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text(encoding="utf-8"))
    assert m["end_reason"] == "completed" and m["loop"] == "native"
    speed_pct = 100.0 * (m["speed_mean_rpm"] - 1000.0) / 1000.0
    torque_pct = 100.0 * (m["torque_mean_nm"] - 10.0) / 10.0
    print(f"im-2k2 / im-foc, 1000 rpm, 10 N·m: speed {speed_pct:+.4f} %, torque mean {torque_pct:+.4f} %")
    assert abs(speed_pct) <= 0.5
    assert abs(torque_pct) <= 1.0


def test_the_c_loop_runs_the_im_as_the_python_loop_does() -> None:
    sc = load_scenario("steady").with_overrides(speed_rpm=1000.0, load_nm=5.0, settle_s=0.02, duration_s=0.03)
    py, na = reference_and_c_records(RunConfig(motor=load_motor("im-2k2"), scenario=sc, controller="im-foc"))
    assert py.shape[0] == 500
    assert_bit_identical(py, na)
    assert abs(na["i_d"][-100:].mean()) > 1.0  # the flux current flows (flux-frame i_d of the plant's sample)
