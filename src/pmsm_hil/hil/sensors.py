"""Sensor models applied to the plant sample: ADC quantisation and noise (seeded), encoder resolution."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pmsm_hil.hil.errors import ParameterError

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, slots=True)
class SensorConfig:
    """adc_lsb_a: current quantisation step [A] (0: ideal); noise_std_a: Gaussian current noise [A];
    encoder_counts: counts per mechanical revolution (0: ideal angle); seed for the noise."""

    adc_lsb_a: float = 0.0
    noise_std_a: float = 0.0
    encoder_counts: int = 0
    seed: int = 0

    def __post_init__(self) -> None:
        if not (self.adc_lsb_a >= 0 and math.isfinite(self.adc_lsb_a)):
            raise ParameterError(f"sensor 'adc_lsb_a' must be ≥ 0 A, got {self.adc_lsb_a}")
        if not (self.noise_std_a >= 0 and math.isfinite(self.noise_std_a)):
            raise ParameterError(f"sensor 'noise_std_a' must be ≥ 0 A, got {self.noise_std_a}")
        if self.encoder_counts < 0:
            raise ParameterError(f"sensor 'encoder_counts' must be ≥ 0, got {self.encoder_counts}")

    @property
    def ideal(self) -> bool:
        """True when the sensors pass the exact plant values through."""
        return self.adc_lsb_a == 0 and self.noise_std_a == 0 and self.encoder_counts == 0


class SensorModel:
    """Turns exact plant values into measured ones; noise drawn in blocks from a seeded generator."""

    _BLOCK = 4096

    def __init__(self, cfg: SensorConfig, pole_pairs: int) -> None:
        self.cfg = cfg
        self.pole_pairs = pole_pairs
        #: made at the first draw (the same draws): numpy.random's import (a dozen extension modules) only where
        #: noise is drawn
        self._rng: np.random.Generator | None = None
        self._noise: list[float] = []

    def _refill(self) -> None:
        if self._rng is None:
            self._rng = np.random.default_rng(self.cfg.seed)
        self._noise = (self._rng.standard_normal(self._BLOCK) * self.cfg.noise_std_a).tolist()

    def _next_noise(self) -> float:
        if not self._noise:
            self._refill()
        return self._noise.pop()

    def take_noise(self, n: int) -> np.ndarray:
        """The next `n` noise values [A] in the order `currents` would use them (for a native loop)."""
        out = np.empty(n, dtype=np.float64)
        i = 0
        while i < n:
            if not self._noise:
                self._refill()
            m = min(n - i, len(self._noise))
            chunk = self._noise[-m:]
            del self._noise[-m:]
            out[i:i + m] = chunk[::-1]
            i += m
        return out

    def currents(self, i_a: float, i_b: float, i_c: float) -> tuple[float, float, float]:
        """Measured phase currents [A]."""
        cfg = self.cfg
        if cfg.noise_std_a:
            i_a, i_b, i_c = i_a + self._next_noise(), i_b + self._next_noise(), i_c + self._next_noise()
        if cfg.adc_lsb_a:
            q = cfg.adc_lsb_a
            i_a, i_b, i_c = round(i_a / q) * q, round(i_b / q) * q, round(i_c / q) * q
        return i_a, i_b, i_c

    def angle(self, theta_e: float) -> float:
        """Measured electrical angle [rad]: the encoder step is 2π·p/counts electrical (index at θe = 0)."""
        if not self.cfg.encoder_counts:
            return theta_e
        step = _TWO_PI * self.pole_pairs / self.cfg.encoder_counts
        return (math.floor(theta_e / step) * step) % _TWO_PI
