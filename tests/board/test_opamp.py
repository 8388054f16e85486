"""OPAMP1..6 of the virtual STM32G474 against RM0440: the PGA gain and input an ADC's internal channel sees, the
follower and the inverting PGA path, LOCK, and the offset calibration driven as HAL_OPAMP_SelfCalibrate drives it
(CALOUT settling after each trim step)."""

from __future__ import annotations

import pytest

from pmsm_hil.sim_target.stm32g4.peripherals.base import REGISTRY, BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.opamp import OFFTRIM_S, Opamp
from tests.board.fake_bus import FakeBus

OPAEN, USERTRIM, OPAINTOEN, CALON, CALOUT, LOCK = 1, 1 << 4, 1 << 8, 1 << 11, 1 << 30, 1 << 31
PGA, FOLLOWER, STANDALONE = 0b10 << 5, 0b11 << 5, 0b00 << 5
TRIMN, TRIMP = 24, 19


def vp(sel: int) -> int:
    return sel << 2


def gain(code: int) -> int:
    return code << 14


@pytest.fixture()
def opamp(bus: FakeBus) -> Opamp:
    return bus.add_model("OPAMP", Opamp)


def test_registered_at_rm0440_address_with_zero_reset(opamp: Opamp) -> None:
    assert "OPAMP" in REGISTRY and opamp.base == 0x4001_0300
    assert [opamp.read(4 * i, 4, 0) for i in range(12)] == [0] * 12


def test_pga_gain_and_input_seen_by_each_amplifiers_adc_channel(opamp: Opamp) -> None:
    # OPAMP1: PGA x16 from VINP2, output to ADC1 IN13; OPAMP3 follower from VINP1, to ADC2 IN18 and ADC3 IN13
    opamp.write(0x00, 4, OPAEN | OPAINTOEN | PGA | vp(2) | gain(0b00011), 0)
    opamp.write(0x08, 4, OPAEN | OPAINTOEN | FOLLOWER | vp(1), 0)
    assert opamp.gain_and_source("ADC1", 13) == (16.0, "OPAMP1_VINP2")
    assert opamp.gain_and_source("ADC2", 18) == (1.0, "OPAMP3_VINP1")
    assert opamp.gain_and_source("ADC3", 13) == (1.0, "OPAMP3_VINP1")
    assert opamp.inverting_path("ADC1", 13) is None
    assert opamp.gain_and_source("ADC1", 12) is None  # an external channel
    assert opamp.gain_and_source("ADC2", 16) is None  # OPAMP2's channel, OPAINTOEN clear
    for code, expected in enumerate((2, 4, 8, 16, 32, 64)):
        opamp.write(0x14, 4, OPAEN | OPAINTOEN | PGA | gain(code), 0)
        assert opamp.gain_and_source("ADC4", 17) == (expected, "OPAMP6_VINP0")


def test_inverting_pga_path_through_vinm0(opamp: Opamp) -> None:
    # PGA_GAIN 01 011: x16 from VINP, -15 from VINM0 (bipolar current sensing with a bias on VINP)
    opamp.write(0x04, 4, OPAEN | OPAINTOEN | PGA | gain(0b01011), 0)
    assert opamp.gain_and_source("ADC2", 16) == (16.0, "OPAMP2_VINP0")
    assert opamp.inverting_path("ADC2", 16) == (-15.0, "OPAMP2_VINM0")


def test_modes_the_model_cannot_answer_are_named(opamp: Opamp) -> None:
    opamp.write(0x0C, 4, OPAINTOEN | PGA, 0)
    with pytest.raises(BoardError, match=r"OPAMP4 \(output to ADC5 channel 5\) is converted while OPAEN is clear"):
        opamp.gain_and_source("ADC5", 5)
    opamp.write(0x10, 4, OPAEN | OPAINTOEN | STANDALONE, 0)
    with pytest.raises(BoardError, match=r"OPAMP5_CSR: VM_SEL = 0b00 \(standalone"):
        opamp.gain_and_source("ADC5", 3)
    opamp.write(0x10, 4, OPAEN | OPAINTOEN | PGA | gain(0b00110), 0)
    with pytest.raises(BoardError, match="PGA_GAIN = 0b00110 is reserved"):
        opamp.gain_and_source("ADC5", 3)
    with pytest.raises(BoardError, match="T1CMEN"):
        opamp.write(0x18, 4, 1 << 3, 0)
    with pytest.raises(BoardError, match=r"OPAMP at offset 0x030 \(0x40010330\)"):
        opamp.read(0x30, 4, 0)


def test_lock_freezes_the_csr_until_reset(opamp: Opamp) -> None:
    opamp.write(0x00, 4, OPAEN | PGA | LOCK, 0)
    opamp.write(0x00, 4, 0, 0)
    assert opamp.read(0x00, 4, 0) == OPAEN | PGA | LOCK and opamp.ignored_writes == 1
    opamp.reset()
    assert opamp.read(0x00, 4, 0) == 0


def self_calibrate(opamp: Opamp, offset: int, calsel: int, shift: int, step: int, start: int) -> tuple[int, int]:
    """The trim search of ST's drivers (mid-scale, halving steps, OUTCAL high means trim higher, a last check), each
    step read `step` cycles after the trim write; returns (trim found, the cycle it ended)."""
    now = start
    base = OPAEN | USERTRIM | CALON | (calsel << 12)
    trim, delta = 16, 8
    while delta:
        opamp.write(offset, 4, base | (trim << shift), now)
        now += step
        trim += delta if opamp.read(offset, 4, now) & CALOUT else -delta
        delta >>= 1
    opamp.write(offset, 4, base | (trim << shift), now)
    now += step
    if opamp.read(offset, 4, now) & CALOUT:
        trim += 1
        opamp.write(offset, 4, base | (trim << shift), now)
    return trim, now


def test_self_calibration_finds_the_trim_that_cancels_the_offset(bus: FakeBus, opamp: Opamp) -> None:
    settle = round(OFFTRIM_S * bus.sysclk_hz)
    opamp.ideal_trim[1] = (11, 22)
    n, now = self_calibrate(opamp, 0x04, 3, TRIMN, 2 * settle, 0)  # N at 90 % VDDA
    p, now = self_calibrate(opamp, 0x04, 1, TRIMP, 2 * settle, now)  # P at 10 % VDDA
    assert (n, p) == (11, 22)
    # CALOUT follows a trim change only after the settling time
    now += settle
    assert not opamp.read(0x04, 4, now) & CALOUT
    opamp.write(0x04, 4, OPAEN | USERTRIM | CALON | (3 << 12) | (0 << TRIMN), now)
    assert not opamp.read(0x04, 4, now + settle - 1) & CALOUT
    assert opamp.read(0x04, 4, now + settle) & CALOUT


class G431Part:
    name = "stm32g431"


def test_the_g431_has_opamp1_to_3() -> None:
    bus = FakeBus()
    bus.part = G431Part()  # type: ignore[attr-defined]
    opamp = bus.add("OPAMP")
    assert isinstance(opamp, Opamp) and opamp.count == 3
    opamp.write(0x08, 4, OPAEN | OPAINTOEN | FOLLOWER, 0)
    assert opamp.gain_and_source("ADC2", 18) == (1.0, "OPAMP3_VINP0")
    with pytest.raises(BoardError, match=r"OPAMP at offset 0x00c \(0x4001030c\)"):
        opamp.write(0x0C, 4, OPAEN, 0)
    with pytest.raises(BoardError, match=r"OPAMP at offset 0x024"):
        opamp.read(0x24, 4, 0)
