"""The CORDIC co-processor of the virtual STM32G474 against RM0440: each function with its argument and result
scaling in q1.31 and q1.15, the error the configured number of iterations leaves, RRDY timing and the interrupt,
driven as the LL/HAL drivers drive it."""

from __future__ import annotations

import math

import pytest

from pmsm_hil.sim_target.stm32g4.peripherals.base import REGISTRY, BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.cordic import Cordic, evaluate, from_q, to_q
from tests.board.fake_bus import FakeBus

CSR, WDATA, RDATA = 0, 4, 8
IEN, NRES, NARGS, RESSIZE, ARGSIZE, RRDY = 1 << 16, 1 << 19, 1 << 20, 1 << 21, 1 << 22, 1 << 31
COS, SIN, PHASE, MODULUS, ATAN, COSH, SINH, ATANH, LN, SQRT = range(10)


def csr(func: int, precision: int = 6, scale: int = 0, flags: int = 0) -> int:
    return func | (precision << 4) | (scale << 8) | flags


@pytest.fixture()
def cordic(bus: FakeBus) -> Cordic:
    return bus.add_model("CORDIC", Cordic)


def q31(value: float) -> int:
    return to_q(value, 32)


def test_registered_with_the_rm0440_reset_value(cordic: Cordic) -> None:
    assert "CORDIC" in REGISTRY and cordic.base == 0x4002_0C00
    assert cordic.read(CSR, 4, 0) == 0x50


def test_sine_and_cosine_in_q131_with_two_arguments_and_two_results(cordic: Cordic) -> None:
    cordic.write(CSR, 4, csr(SIN, flags=NRES | NARGS), 0)
    cordic.write(WDATA, 4, q31(1 / 6), 10)  # 30 degrees
    cordic.write(WDATA, 4, q31(0.5), 10)  # modulus 0.5
    assert not cordic.read(CSR, 4, 15) & RRDY  # 6 cycles for 24 iterations
    assert cordic.read(CSR, 4, 16) & RRDY
    sin, cos = from_q(cordic.read(RDATA, 4, 16), 32), from_q(cordic.read(RDATA, 4, 16), 32)
    assert sin == pytest.approx(0.25, abs=2 ** -22) and cos == pytest.approx(0.5 * math.sqrt(3) / 2, abs=2 ** -22)
    assert not cordic.read(CSR, 4, 17) & RRDY
    # one argument: ARG2 keeps the modulus written before
    cordic.write(CSR, 4, csr(COS), 20)
    cordic.write(WDATA, 4, q31(-2 / 3), 20)
    assert from_q(cordic.read(RDATA, 4, 30), 32) == pytest.approx(0.5 * math.cos(-2 * math.pi / 3), abs=2 ** -22)


def test_q115_packs_both_arguments_and_both_results_in_one_word(cordic: Cordic) -> None:
    cordic.write(CSR, 4, csr(PHASE, precision=4, flags=ARGSIZE | RESSIZE), 0)
    x, y = to_q(-0.3, 16), to_q(0.4, 16)
    cordic.write(WDATA, 4, x | (y << 16), 0)
    word = cordic.read(RDATA, 4, 4)
    assert from_q(word, 16) == pytest.approx(math.atan2(0.4, -0.3) / math.pi, abs=2 ** -14)
    assert from_q(word >> 16, 16) == pytest.approx(0.5, abs=2 ** -14)


@pytest.mark.parametrize(("func", "scale", "arg", "expected"), [
    (MODULUS, 0, (0.6, -0.8), 1.0 - 2 ** -31),  # saturated to the largest q1.31 value
    (ATAN, 3, (5.0 / 8,), math.atan(5.0) / math.pi / 8),
    (COSH, 1, (0.3,), math.cosh(0.6) / 2),
    (SINH, 1, (-0.4,), math.sinh(-0.8) / 2),
    (ATANH, 1, (0.35,), math.atanh(0.7) / 2),
    (LN, 3, (5.0 / 8,), math.log(5.0) / 16),
    (SQRT, 1, (1.2 / 2,), math.sqrt(1.2) / 2),
])
def test_each_function_with_rm0440_scaling(cordic: Cordic, func: int, scale: int, arg: tuple[float, ...],
                                           expected: float) -> None:
    cordic.write(CSR, 4, csr(func, scale=scale, flags=NARGS if len(arg) == 2 else 0), 0)
    for value in arg:
        cordic.write(WDATA, 4, q31(value), 0)
    assert from_q(cordic.read(RDATA, 4, 6), 32) == pytest.approx(expected, abs=2 ** -20)


def test_the_error_falls_about_one_bit_per_iteration() -> None:
    """The measured bound of sine over a grid of angles: below 2^-(4p - 2) for PRECISION p (24 iterations: 2^-22),
    down to the q1.31 resolution."""
    angles = [i / 500 - 1 for i in range(1000)]
    previous = 1.0
    for precision in (1, 2, 3, 4, 5, 6, 8):
        error = max(abs(evaluate(SIN, a, 1.0, 0, 4 * precision)[0] - math.sin(a * math.pi)) for a in angles)
        assert error < 2.0 ** -(4 * precision - 2)
        assert error < previous / 8
        previous = error


def test_the_interrupt_follows_rrdy_and_the_last_read(bus: FakeBus, cordic: Cordic) -> None:
    cordic.write(CSR, 4, csr(COS, precision=3, flags=IEN), 100)
    cordic.write(WDATA, 4, q31(0.25), 100)
    assert cordic.next_event(100) == 103
    cordic.advance(102)
    assert bus.pended == []
    cordic.advance(103)
    assert bus.pended == [100] and cordic.next_event(103) is None
    cordic.read(RDATA, 4, 104)
    assert bus.cleared == [100]


def test_unmodelled_and_reserved_settings_are_named(cordic: Cordic) -> None:
    with pytest.raises(BoardError, match="DMAREN, DMAWEN"):
        cordic.write(CSR, 4, csr(COS, flags=1 << 17), 0)
    with pytest.raises(BoardError, match="FUNC = 12 is reserved"):
        cordic.write(CSR, 4, csr(12), 0)
    cordic.write(CSR, 4, csr(LN, scale=0), 0)
    with pytest.raises(BoardError, match=r"SCALE = 0 is outside natural logarithm's range \(1 to 4\)"):
        cordic.write(WDATA, 4, q31(0.5), 0)
    with pytest.raises(BoardError, match=r"CORDIC at offset 0x00c"):
        cordic.read(0xC, 4, 0)
