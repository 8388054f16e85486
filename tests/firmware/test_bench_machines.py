"""`hil bench controllers` times mptc1..3 on the six-phase machine (not on refused three-phase frames)."""

from __future__ import annotations

import math

import pytest

from pmsm_hil.app.cli import bench_controllers
from pmsm_hil.app.cli.bench_machines import SIX_PHASE_IDS, THREE_PHASE, inputs, machine_for


def test_six_phase_inputs_are_a_balanced_q_current() -> None:
    m = machine_for(9)
    assert m.pole_pairs == 4 and len(m.angles) == 6 and machine_for(1) is THREE_PHASE
    assert m.i_q == pytest.approx(40.0 / 1.2)
    for currents, th in inputs(m, 5):
        # amplitude-invariant VSD alpha row (1/3) recovers -i_q sin(theta)
        alpha = sum(i * math.cos(a) for i, a in zip(currents, m.angles, strict=True)) / 3.0
        assert alpha == pytest.approx(-m.i_q * math.sin(th), abs=1e-9)
        assert sum(currents[:3]) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("controller_id", sorted(SIX_PHASE_IDS))
def test_mptc_controllers_are_timed_with_an_ok_status(controller_id: int) -> None:
    fig = bench_controllers.time_controller(controller_id, 200, 1)
    assert fig.name.startswith("mptc") and fig.ns_per_step > 0.0
    assert fig.split_ns[2] > 0.0


def test_driver_source_writes_the_machine_parameters() -> None:
    src = bench_controllers.driver_source(machine_for(8))
    assert "m.n_phases = 6u" in src and "hil_fw_set_param" in src
    assert "1.000000000e-01f" in src  # psi_f
