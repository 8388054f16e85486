"""Inverter vector geometry: hexagon, MPCC vector numbering, mean voltage, six-phase VSD."""

from __future__ import annotations

import numpy as np

from pmsm_hil.dashboards.geometry import (
    VECTOR_STATE,
    hexagon,
    linear_limit_circle,
    mean_voltage_ab,
    six_phase_vsd,
    state_voltage_ab,
)

VDC = 300.0


def test_active_vectors_on_hexagon_at_vector_id_angles() -> None:
    for vid in range(1, 7):
        u = state_voltage_ab(VECTOR_STATE[vid], VDC)
        assert abs(np.hypot(*u) - 2.0 / 3.0 * VDC) < 1e-9
        assert abs(np.degrees(np.arctan2(u[1], u[0])) % 360.0 - 60.0 * (vid - 1)) < 1e-9
    assert np.allclose(state_voltage_ab([0, 7], VDC), 0.0)


def test_hexagon_closed_and_inscribed_circle() -> None:
    h = hexagon(VDC)
    assert h.shape == (7, 2) and np.allclose(h[0], h[-1])
    assert np.allclose(np.hypot(h[:, 0], h[:, 1]), 200.0)
    c = linear_limit_circle(VDC)
    assert np.allclose(np.hypot(c[:, 0], c[:, 1]), VDC / np.sqrt(3.0))


def test_mean_voltage_weights_durations_and_ignores_unused_entries() -> None:
    states = np.array([[4, 6, 7], [4, 6, 0]], dtype=np.uint8)
    durs = np.array([[50_000, 50_000, 0], [25_000, 75_000, 99_999]], dtype=np.uint32)
    mean = mean_voltage_ab(states, durs, np.array([2, 2]), VDC)
    v1, v2 = state_voltage_ab(4, VDC), state_voltage_ab(6, VDC)
    assert np.allclose(mean[0], 0.5 * (v1 + v2))
    assert np.allclose(mean[1], 0.25 * v1 + 0.75 * v2)


def test_six_phase_vsd_sets_and_xy() -> None:
    ab, xy = six_phase_vsd([0b100000, 0b000100, 0b111111, 0], VDC)
    assert np.allclose(ab[0], [VDC / 3.0, 0.0]) and np.allclose(xy[0], [VDC / 3.0, 0.0])
    # phase U sits at 30° in αβ and at 150° in x-y
    assert abs(np.degrees(np.arctan2(ab[1][1], ab[1][0])) - 30.0) < 1e-9
    assert abs(np.degrees(np.arctan2(xy[1][1], xy[1][0])) - 150.0) < 1e-9
    assert np.allclose(ab[2:], 0.0) and np.allclose(xy[2:], 0.0)


def test_duty_voltage_is_the_mean_of_the_carrier_comparison() -> None:
    """Duty cycles (1, 0, 0) are V1 for the whole period; (0.5 + δ) on every leg is zero voltage; a 7-segment
    period's duration-weighted mean state voltage equals the duties' voltage."""
    from pmsm_hil.dashboards.geometry import duty_voltage_ab, state_voltage_ab
    from pmsm_hil.hil.pwm import DUTY_FULL, duty_sequence
    vdc = 300.0
    np.testing.assert_allclose(duty_voltage_ab(np.array([[1.0, 0.0, 0.0]]), vdc)[0],
                               state_voltage_ab(np.array(4), vdc))
    np.testing.assert_allclose(duty_voltage_ab(np.array([[0.7, 0.7, 0.7]]), vdc)[0], [0.0, 0.0], atol=1e-12)
    duties = (0.8, 0.5, 0.2)
    states, durs = duty_sequence([round(d * DUTY_FULL) for d in duties], 100_000)
    v = state_voltage_ab(np.array(states), vdc)
    mean = (v * np.array(durs)[:, None]).sum(axis=0) / 100_000
    np.testing.assert_allclose(duty_voltage_ab(np.array([duties]), vdc)[0], mean, atol=1e-2)
