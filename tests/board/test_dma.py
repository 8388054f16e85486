"""DMA1/DMA2 and DMAMUX1 of the virtual STM32G474 against RM0440: requests routed by DMAREQ_ID, circular and normal
transfers, HT/TC flags and their interrupt lines, data widths, memory-to-memory and the registers frozen while a
channel runs, driven register by register as HAL/LL drivers do, on a fake board."""

from __future__ import annotations

import pytest

from pmsm_hil.sim_target.stm32g4.peripherals.base import REGISTRY, BoardError, Peripheral
from pmsm_hil.sim_target.stm32g4.peripherals.dma import Dma
from pmsm_hil.sim_target.stm32g4.peripherals.dmamux import REQUEST_IDS, Dmamux
from tests.board.fake_bus import SRAM, FakeBus

#: every test with TIM1 and the ADCs in C and with their Python reference
pytestmark = pytest.mark.usefixtures("tim_adc_models")

EN, TCIE, HTIE, TEIE, DIR, CIRC, PINC, MINC = (1 << b for b in range(8))
MEM2MEM = 1 << 14
PSIZE16, MSIZE16, PSIZE32, MSIZE32 = 1 << 8, 1 << 10, 2 << 8, 2 << 10
ISR, IFCR = 0x00, 0x04


def ch_reg(channel: int, reg: str) -> int:
    """The offset of CCRx/CNDTRx/CPARx/CMARx of `channel` (1-based)."""
    return 0x08 + 0x14 * (channel - 1) + {"CCR": 0, "CNDTR": 4, "CPAR": 8, "CMAR": 12}[reg]


class DataRegister(Peripheral):
    """A stand-in for a peripheral's data register at offset 0x40 (an ADC's DR): each read returns the next sample
    and counts, as a DMA read clears the chip's EOC; writes are collected."""

    base = 0x5000_0000
    size = 0x100

    def reset(self) -> None:
        self.samples = iter(range(0x100, 0x10000))
        self.reads = 0
        self.written: list[int] = []

    def read(self, offset: int, size: int, now: int) -> int:
        assert offset == 0x40
        self.reads += 1
        return next(self.samples)

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        assert offset == 0x40
        self.written.append(value)


@pytest.fixture()
def bus() -> FakeBus:
    bus = FakeBus()
    for name in ("DMA1", "DMA2", "DMAMUX1"):
        bus.add(name)
    bus.models["DR"] = DataRegister(bus)
    return bus


def dma(bus: FakeBus, name: str = "DMA1") -> Dma:
    model = bus.peripheral(name)
    assert isinstance(model, Dma)
    return model


def mux(bus: FakeBus) -> Dmamux:
    model = bus.peripheral("DMAMUX1")
    assert isinstance(model, Dmamux)
    return model


def setup_channel(bus: FakeBus, name: str, channel: int, request: str, ccr: int, count: int, par: int,
                  mar: int) -> None:
    """HAL_DMA_Init + HAL_DMA_Start_IT: the channel off, DMAMUX CxCR, CNDTR/CPAR/CMAR, then CCR with EN."""
    d = dma(bus, name)
    d.write(ch_reg(channel, "CCR"), 4, 0, 0)
    mux_channel = channel - 1 + (8 if name == "DMA2" else 0)
    mux(bus).write(4 * mux_channel, 4, REQUEST_IDS[request], 0)
    mux(bus).write(0x84, 4, 1 << mux_channel, 0)  # CFR, as HAL_DMA_Init clears the overrun flag
    d.write(ch_reg(channel, "CNDTR"), 4, count, 0)
    d.write(ch_reg(channel, "CPAR"), 4, par, 0)
    d.write(ch_reg(channel, "CMAR"), 4, mar, 0)
    d.write(ch_reg(channel, "CCR"), 4, ccr & ~EN, 0)
    d.write(ch_reg(channel, "CCR"), 4, ccr, 0)


def test_the_models_are_registered_at_rm0440_addresses_with_zero_reset_values(bus: FakeBus) -> None:
    assert {"DMA1", "DMA2", "DMAMUX1"} <= set(REGISTRY)
    assert (dma(bus).base, dma(bus, "DMA2").base, mux(bus).base) == (0x4002_0000, 0x4002_0400, 0x4002_0800)
    assert dma(bus).irq_lines == (11, 12, 13, 14, 15, 16, 17, 96)
    assert dma(bus, "DMA2").irq_lines == (56, 57, 58, 59, 60, 97, 98, 99)
    for channel in range(1, 9):
        for reg in ("CCR", "CNDTR", "CPAR", "CMAR"):
            assert dma(bus).read(ch_reg(channel, reg), 4, 0) == 0
    assert dma(bus).read(ISR, 4, 0) == 0
    assert [mux(bus).read(4 * c, 4, 0) for c in range(16)] == [0] * 16
    assert (REQUEST_IDS["ADC1"], REQUEST_IDS["ADC2"], REQUEST_IDS["USART1_TX"], REQUEST_IDS["TIM1_UP"]) == (
        5, 36, 25, 46)


def test_adc_samples_go_to_a_circular_buffer_with_half_and_full_transfer_interrupts(bus: FakeBus) -> None:
    setup_channel(bus, "DMA1", 1, "ADC1", EN | TCIE | HTIE | CIRC | MINC | PSIZE16 | MSIZE16, 4, 0x5000_0040,
                  SRAM + 0x100)
    assert mux(bus).request(REQUEST_IDS["ADC1"], 10)
    assert dma(bus).read(ch_reg(1, "CNDTR"), 4, 10) == 3
    assert dma(bus).read(ISR, 4, 10) == 0 and bus.pended == []
    assert mux(bus).request(REQUEST_IDS["ADC1"], 20)
    assert dma(bus).read(ISR, 4, 20) == 0b0101  # HTIF1 | GIF1
    assert bus.pended == [11]
    dma(bus).write(IFCR, 4, 0b0100, 25)  # CHTIF1: the line drops with the last enabled flag
    assert dma(bus).read(ISR, 4, 25) == 0 and bus.cleared == [11]
    for at in (30, 40):
        assert mux(bus).request(REQUEST_IDS["ADC1"], at)
    assert dma(bus).read(ISR, 4, 40) == 0b0011  # TCIF1 | GIF1
    assert bus.pended == [11, 11]
    assert [bus.word(SRAM + 0x100 + 2 * i, 2) for i in range(4)] == [0x100, 0x101, 0x102, 0x103]
    # circular: the count and the addresses reload, the next sample lands at the start again
    assert dma(bus).read(ch_reg(1, "CNDTR"), 4, 40) == 4
    assert mux(bus).request(REQUEST_IDS["ADC1"], 50)
    assert bus.word(SRAM + 0x100, 2) == 0x104
    dma(bus).write(IFCR, 4, 0b0001, 55)  # CGIF1 clears all the channel's flags
    assert dma(bus).read(ISR, 4, 55) == 0


def test_a_normal_transfer_stops_at_its_count_and_further_requests_are_not_served(bus: FakeBus) -> None:
    setup_channel(bus, "DMA1", 3, "ADC2", EN | TCIE | MINC | PSIZE32 | MSIZE32, 2, 0x5000_0040, SRAM)
    assert mux(bus).request(REQUEST_IDS["ADC2"], 1) and mux(bus).request(REQUEST_IDS["ADC2"], 2)
    assert dma(bus).read(ISR, 4, 2) == 0b0111 << 8  # TCIF3 | HTIF3 (after the first of 2 items) | GIF3
    assert bus.pended == [13]
    assert not mux(bus).request(REQUEST_IDS["ADC2"], 3)
    assert not mux(bus).request(REQUEST_IDS["USART1_RX"], 3)  # selected by no channel
    assert mux(bus).unserved == {REQUEST_IDS["ADC2"]: 1, REQUEST_IDS["USART1_RX"]: 1}
    data_register = bus.models["DR"]
    assert isinstance(data_register, DataRegister) and data_register.reads == 2
    assert (bus.word(SRAM), bus.word(SRAM + 4)) == (0x100, 0x101)


def test_usart_tx_from_memory_on_dma2_and_the_data_widths(bus: FakeBus) -> None:
    bus.write_memory(SRAM + 0x40, b"ok\n")
    setup_channel(bus, "DMA2", 2, "USART1_TX", EN | TCIE | DIR | MINC, 3, 0x5000_0040, SRAM + 0x40)
    for at in range(3):
        assert mux(bus).request(REQUEST_IDS["USART1_TX"], at)
    data_register = bus.models["DR"]
    assert isinstance(data_register, DataRegister)
    assert bytes(data_register.written) == b"ok\n"
    assert bus.pended == [57]  # DMA2_Channel2
    # a 32-bit source into 8-bit memory keeps the low byte; an 8-bit source into 32-bit memory is zero-extended
    bus.put(SRAM + 0x200, 0xFFFF_FFFF)
    setup_channel(bus, "DMA1", 8, "TIM1_UP", EN | MINC | PSIZE32, 1, 0x5000_0040, SRAM + 0x200)
    assert mux(bus).request(REQUEST_IDS["TIM1_UP"], 5)
    assert bus.word(SRAM + 0x200) == 0xFFFF_FF00 | (0x100 & 0xFF)
    setup_channel(bus, "DMA1", 7, "TIM1_CH1", EN | MINC | MSIZE32, 1, 0x5000_0040, SRAM + 0x204)
    assert mux(bus).request(REQUEST_IDS["TIM1_CH1"], 6)
    assert bus.word(SRAM + 0x204) == 0x01  # 0x101 read as a byte


def test_memory_to_memory_runs_to_completion_when_enabled(bus: FakeBus) -> None:
    bus.write_memory(SRAM, bytes(range(32)))
    setup_channel(bus, "DMA1", 2, "MEM2MEM", EN | TCIE | MEM2MEM | PINC | MINC | PSIZE32 | MSIZE32, 8, SRAM,
                  SRAM + 0x1000)
    assert bus.read_memory(SRAM + 0x1000, 32) == bytes(range(32))
    assert dma(bus).read(ch_reg(2, "CNDTR"), 4, 0) == 0
    assert dma(bus).read(ISR, 4, 0) == 0b0111 << 4  # GIF2 | TCIF2 | HTIF2
    assert bus.pended == [12]
    assert dma(bus).transfers == 8


def test_configuration_is_frozen_while_the_channel_runs(bus: FakeBus) -> None:
    setup_channel(bus, "DMA1", 1, "ADC1", EN | MINC | PSIZE16 | MSIZE16, 4, 0x5000_0040, SRAM)
    d = dma(bus)
    d.write(ch_reg(1, "CNDTR"), 4, 100, 1)
    d.write(ch_reg(1, "CMAR"), 4, SRAM + 0x800, 1)
    d.write(ch_reg(1, "CCR"), 4, EN | TCIE | MINC | PSIZE32 | MSIZE16, 1)  # only TCIE takes
    assert d.read(ch_reg(1, "CCR"), 4, 1) == EN | TCIE | MINC | PSIZE16 | MSIZE16
    assert (d.read(ch_reg(1, "CNDTR"), 4, 1), d.read(ch_reg(1, "CMAR"), 4, 1)) == (4, SRAM)
    assert d.ignored_writes == 3
    assert mux(bus).request(REQUEST_IDS["ADC1"], 2)
    d.write(ch_reg(1, "CCR"), 4, 0, 3)
    # stopped: CNDTR keeps the items left (what HAL's UART DMA stop reads to count the bytes received)
    assert d.read(ch_reg(1, "CNDTR"), 4, 3) == 3
    d.write(ch_reg(1, "CNDTR"), 4, 100, 3)
    assert d.read(ch_reg(1, "CNDTR"), 4, 3) == 100


def test_unmodelled_features_and_registers_end_with_an_error_naming_them(bus: FakeBus) -> None:
    with pytest.raises(BoardError, match=r"C3CR: SE \(synchronisation\) is not modelled"):
        mux(bus).write(4 * 3, 4, 1 << 16, 0)
    with pytest.raises(BoardError, match=r"RG1CR: GE"):
        mux(bus).write(0x104, 4, 1 << 16, 0)
    mux(bus).write(0x104, 4, 0, 0)  # HAL_DMA_Init clears a generator it does not use
    with pytest.raises(BoardError, match=r"DMA1 at offset 0x0a8 \(0x400200a8\)"):
        dma(bus).read(0xA8, 4, 0)
    with pytest.raises(BoardError, match="PSIZE = 3 is reserved"):
        setup_channel(bus, "DMA1", 1, "ADC1", EN | (3 << 8), 1, 0x5000_0040, SRAM)
    setup_channel(bus, "DMA1", 4, "ADC1", EN, 1, 0x4000_0000, SRAM)
    with pytest.raises(BoardError, match=r"DMA1 channel 4 \(0x40000000 -> 0x20000000\)"):
        mux(bus).request(REQUEST_IDS["ADC1"], 0)


class G431Part:
    name = "stm32g431"


def test_on_the_g431_each_controller_has_6_channels_and_dmamux_12(bus: FakeBus) -> None:
    small = FakeBus()
    small.part = G431Part()  # type: ignore[attr-defined]
    for name in ("DMA1", "DMA2", "DMAMUX1"):
        small.add(name)
    small.models["DR"] = DataRegister(small)
    assert len(dma(small).channels) == 6 and len(dma(small, "DMA2").channels) == 6
    with pytest.raises(BoardError, match="DMA1 at offset 0x080"):
        dma(small).read(ch_reg(7, "CCR"), 4, 0)
    with pytest.raises(BoardError, match="DMAMUX1 at offset 0x030"):
        mux(small).read(4 * 12, 4, 0)
    # HAL's DMA2 channel 1 on the G431 is DMAMUX1 channel 6
    mux(small).write(4 * 6, 4, REQUEST_IDS["USART1_TX"], 0)
    d2 = dma(small, "DMA2")
    small.write_memory(SRAM, b"x")
    d2.write(ch_reg(1, "CNDTR"), 4, 1, 0)
    d2.write(ch_reg(1, "CPAR"), 4, 0x5000_0040, 0)
    d2.write(ch_reg(1, "CMAR"), 4, SRAM, 0)
    d2.write(ch_reg(1, "CCR"), 4, EN | TCIE | DIR, 0)
    assert mux(small).request(REQUEST_IDS["USART1_TX"], 1)
    assert small.pended == [56]
    assert len(dma(bus).channels) == 8 and len(mux(bus).cxcr) == 16
