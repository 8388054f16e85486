"""The ADC's regular conversions read by DMA (its DMAMUX request at each conversion end, the channel reading DR
and clearing EOC) and an internal channel converting an OPAMP's PGA output, on the fake board."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.sim_target.stm32g4.board import load_models
from pmsm_hil.sim_target.stm32g4.board_file import load_board
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from tests.board.fake_bus import SRAM, FakeBus

#: every test with TIM1 and the ADCs in C and with their Python reference
pytestmark = pytest.mark.usefixtures("tim_adc_models")

load_models()

ISR, CR, CFGR, SMPR1, SQR1, DR = 0x00, 0x08, 0x0C, 0x14, 0x30, 0x40
EOC, EOS = 4, 8
ADEN, ADSTART, ADVREGEN = 1, 4, 1 << 28
DMAEN, DMACFG, CONT = 1, 2, 1 << 13
CCR_COMMON = 0x08
OPAEN, OPAINTOEN, PGA = 1, 1 << 8, 0b10 << 5
# DMA1 channel 1: CCR, CNDTR, CPAR, CMAR; DMAMUX1 C0CR feeds it
DMA_CCR, DMA_CNDTR, DMA_CPAR, DMA_CMAR = 0x08, 0x0C, 0x10, 0x14
EN, TCIE, CIRC, MINC, PSIZE16, MSIZE16 = 1, 2, 1 << 5, 1 << 7, 1 << 8, 1 << 10


class AnalogBus(FakeBus):
    """The fake board with an analog front end: volts by (adc or amplifier input, channel)."""

    def __init__(self, volts: dict[tuple[str, int], float]) -> None:
        super().__init__()
        self.volts = volts

    def analog_voltage(self, adc: str, channel: int, now: int) -> float:
        return 3.3 if channel < 0 else self.volts.get((adc, channel), 0.0)


def enabled_adc1(bus: AnalogBus) -> int:
    """ADC1 powered, enabled and ready (HCLK/1 clock); the cycle it is ready at."""
    for name in ("TIM1", "ADC12_COMMON", "ADC1", "ADC2", "DMA1", "DMA2", "DMAMUX1", "OPAMP"):
        bus.add(name)
    bus.models["ADC12_COMMON"].write(CCR_COMMON, 4, 1 << 16, 0)  # CKMODE HCLK/1
    adc = bus.models["ADC1"]
    adc.write(CR, 4, ADVREGEN, 0)
    adc.write(CR, 4, ADVREGEN | ADEN, 10)
    adc.advance(100)
    assert adc.read(ISR, 4, 100) & 1  # ADRDY
    return 100


def run(bus: AnalogBus, until: int) -> None:
    adc = bus.models["ADC1"]
    t = 0
    while (event := adc.next_event(t)) is not None and event <= until:
        adc.advance(event)
        t = event


def test_regular_conversions_go_to_memory_by_dma_and_the_opamp_gain_applies() -> None:
    bus = AnalogBus({("ADC1", 1): 0.5, ("ADC1", 2): 1.0, ("OPAMP1_VINP0", 0): 0.2})
    now = enabled_adc1(bus)
    # OPAMP1 as a PGA x4 from VINP0 into ADC1 IN13
    bus.models["OPAMP"].write(0x00, 4, OPAEN | OPAINTOEN | PGA | (0b00001 << 14), now)
    dma, mux, adc = bus.models["DMA1"], bus.models["DMAMUX1"], bus.models["ADC1"]
    mux.write(0x00, 4, 5, now)  # C0CR.DMAREQ_ID = ADC1
    dma.write(DMA_CPAR, 4, adc.base + DR, now)
    dma.write(DMA_CMAR, 4, SRAM + 0x100, now)
    dma.write(DMA_CNDTR, 4, 6, now)
    dma.write(DMA_CCR, 4, EN | CIRC | MINC | PSIZE16 | MSIZE16, now)
    adc.write(SMPR1, 4, 0, now)
    adc.write(SQR1, 4, 2 | 1 << 6 | 2 << 12 | 13 << 18, now)  # L = 2: IN1, IN2, IN13
    adc.write(CFGR, 4, 0x8000_0000 | DMAEN | DMACFG, now)
    adc.write(CR, 4, ADVREGEN | ADEN | ADSTART, now)
    run(bus, now + 1000)
    codes = [bus.word(SRAM + 0x100 + 2 * i, 2) for i in range(3)]
    assert codes == [round(v / 3.3 * 4095) for v in (0.5, 1.0, 4 * 0.2)]
    assert not adc.read(ISR, 4, now + 1000) & EOC  # the DMA read DR
    assert dma.read(DMA_CNDTR, 4, now + 1000) == 3


def test_a_dr_read_clears_eoc_and_without_dmaen_no_request_is_made() -> None:
    bus = AnalogBus({("ADC1", 1): 1.65})
    now = enabled_adc1(bus)
    adc = bus.models["ADC1"]
    adc.write(SQR1, 4, 1 << 6, now)
    adc.write(CR, 4, ADVREGEN | ADEN | ADSTART, now)
    run(bus, now + 1000)
    assert adc.read(ISR, 4, now + 1000) & (EOC | EOS) == EOC | EOS
    assert adc.read(DR, 4, now + 1000) == 2048
    assert adc.read(ISR, 4, now + 1000) & (EOC | EOS) == EOS
    assert bus.models["DMAMUX1"].unserved == {}  # type: ignore[attr-defined]


def test_a_board_file_describes_an_amplifier_input(tmp_path: Path) -> None:
    source = (Path(__file__).parents[2] / "src/pmsm_hil/sim_target/stm32g4/boards/nucleo_g474re_ihm.toml").read_text()
    board = tmp_path / "board.toml"
    board.write_text(source + '\n[[analog]]\nsignal = "i_b"\nadc = "OPAMP1_VINP0"\noffset_v = 1.65\ngain = 0.01\n')
    assert load_board(board).analog[-1].adc == "OPAMP1_VINP0"
    board.write_text(source + '\n[[analog]]\nsignal = "i_b"\nadc = "OPAMP1_VINP0"\nchannel = 3\noffset_v = 1.65\n'
                     'gain = 0.01\n')
    with pytest.raises(BoardError, match="amplifier input OPAMP1_VINP0 has no channel"):
        load_board(board)
