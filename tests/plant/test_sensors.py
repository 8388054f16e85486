"""Sensor models: ADC quantisation, seeded noise, encoder resolution."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.sensors import SensorConfig, SensorModel


def test_ideal_sensors_pass_values_through() -> None:
    model = SensorModel(SensorConfig(), pole_pairs=3)
    assert SensorConfig().ideal
    assert model.currents(1.2345, -0.5, -0.7345) == (1.2345, -0.5, -0.7345)
    assert model.angle(1.0) == 1.0


def test_adc_quantisation_rounds_to_the_lsb() -> None:
    model = SensorModel(SensorConfig(adc_lsb_a=0.01), pole_pairs=3)
    ia, ib, ic = model.currents(1.2345, -0.5049, 0.0)
    assert ia == pytest.approx(1.23) and ib == pytest.approx(-0.50) and ic == 0.0


def test_noise_is_seeded_and_has_the_requested_spread() -> None:
    a = SensorModel(SensorConfig(noise_std_a=0.05, seed=7), pole_pairs=3)
    b = SensorModel(SensorConfig(noise_std_a=0.05, seed=7), pole_pairs=3)
    xa = np.array([a.currents(0.0, 0.0, 0.0) for _ in range(3000)])
    xb = np.array([b.currents(0.0, 0.0, 0.0) for _ in range(3000)])
    assert np.array_equal(xa, xb)
    assert xa.std() == pytest.approx(0.05, rel=0.05)
    c = SensorModel(SensorConfig(noise_std_a=0.05, seed=8), pole_pairs=3)
    assert not np.array_equal(xa[:10], np.array([c.currents(0.0, 0.0, 0.0) for _ in range(10)]))


def test_the_noise_is_the_seeded_generators_draws_in_order() -> None:
    """The generator is made at the first draw (numpy.random imported only then): the draws are those of
    `default_rng(seed)` made up front, block by block, each block used from its end."""
    model = SensorModel(SensorConfig(noise_std_a=0.05, seed=11), pole_pairs=3)
    block = SensorModel._BLOCK
    draws = np.random.default_rng(11).standard_normal(2 * block) * 0.05
    expected = np.concatenate([draws[:block][::-1], draws[block:][::-1]])
    first = [model.currents(0.0, 0.0, 0.0) for _ in range(5)]
    assert [v for triple in first for v in triple] == expected[:15].tolist()
    assert model.take_noise(2 * block - 15).tolist() == expected[15:].tolist()


def test_encoder_quantises_the_electrical_angle() -> None:
    model = SensorModel(SensorConfig(encoder_counts=1024), pole_pairs=4)
    step = 2 * math.pi * 4 / 1024
    assert model.angle(0.5 * step) == 0.0
    assert model.angle(3.7 * step) == pytest.approx(3 * step)


@pytest.mark.parametrize("kw", [{"adc_lsb_a": -1.0}, {"noise_std_a": float("nan")}, {"encoder_counts": -5}])
def test_bad_sensor_settings_name_the_field(kw: dict[str, float]) -> None:
    with pytest.raises(ParameterError, match=next(iter(kw))):
        SensorConfig(**kw)  # type: ignore[arg-type]
