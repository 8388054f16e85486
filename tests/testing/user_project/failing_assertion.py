"""A deliberately failing assertion (tests/testing/test_plugin.py checks its message and its plot)."""

from pmsm_hil.testing import assert_is_constant


def test_torque_is_flat(hil):
    r = hil.run(settle=0.01, duration=0.02)
    assert_is_constant(r.signal("torque_nm"), around=7.0, tol=0.01, during=(0.01, 0.03))
