"""The saturated flux-map preset in the C period loop. Its closed-loop operating range (mpcc and
foc, 300 and 1500 rpm, 10-100 % of the rated 7 N·m, the operating-range tolerances) is a grid of
tests/runner/test_operating_range.py; here: the C loop runs the kind as the Python loop does, record for record."""

from __future__ import annotations

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from tests.runner.loop_pairs import assert_bit_identical, reference_and_c_records


def test_the_c_loop_runs_the_kind_as_the_python_loop() -> None:
    sc = load_scenario("dyno-steady").with_overrides(settle_s=0.01, duration_s=0.01, load_nm=3.0)
    py, na = reference_and_c_records(RunConfig(motor=load_motor("niu2020-ipmsm-sat"), scenario=sc, controller="mpcc"))
    assert py.shape[0] > 100
    assert_bit_identical(py, na)
    assert abs(na["i_q"][-50:].mean()) > 1.0
