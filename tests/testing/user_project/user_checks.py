"""A user's test file (collected only when named on the command line: tests/testing/test_plugin.py runs it under
--hil-target inproc and spawn). No project import but pmsm_hil.testing."""

import numpy as np

from pmsm_hil.testing import assert_below, assert_is_constant, assert_settles

SIGNALS = ("speed_rpm", "torque_nm", "torque_ref_nm", "i_a", "i_b", "i_c", "i_d", "i_q", "exec_time_us")


def test_signals_cover_the_whole_run(hil):
    # any `hil run` option by name (the plugin's lockstep timeout is 2 s; a very loaded host may stall longer)
    r = hil.run(scenario="steady", speed=1500, load=7, settle=0.02, duration=0.03, lockstep_timeout=5)
    assert r.end_code == 0, r.end_reason
    assert r.mcap_path.is_file() and r.metrics["total_periods"] == 500
    for name in SIGNALS:
        sig = r.signal(name)
        assert len(sig.t) == 500 and sig.t[0] == 0.0, name
        assert np.allclose(np.diff(sig.t), 1e-4), name
    assert_is_constant(r.signal("speed_rpm"), around=1500, tol=15, during=(0.02, 0.05))  # after the start
    assert_settles(r.signal("torque_nm"), to=7.0, tol=1.5, within=0.01)
    assert_below(r.signal("i_q"), 40.0)
    i_sum = r.signal("i_a").y + r.signal("i_b").y + r.signal("i_c").y
    assert np.abs(i_sum).max() < 1e-6  # isolated star point
