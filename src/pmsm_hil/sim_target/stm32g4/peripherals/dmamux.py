"""DMAMUX1 of the STM32G474 (RM0440 "DMA request multiplexer") at 0x40020800: 16 request-line multiplexer channels,
channel c feeding DMA1 channel c + 1 (c = 0..7) or DMA2 channel c - 7 (c = 8..15); on a part with 6-channel DMA
controllers (the G431) 12, channels 6..11 feeding DMA2.

A peripheral that raises a DMA request calls `Dmamux.request(request_id, now)` with its RM0440 request id
(`REQUEST_IDS`, the table "DMAMUX: assignment of multiplexer inputs to resources"); the multiplexer channel whose
CxCR.DMAREQ_ID holds that id passes it to its DMA channel, which moves one item. Synchronisation (CxCR.SE), event
generation (CxCR.EGE) and the four request generators (RGxCR.GE) are not modelled: enabling one ends the run with an
error naming the field.
"""

from __future__ import annotations

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, Peripheral, register
from pmsm_hil.sim_target.stm32g4.peripherals.dma import Dma, channel_count

#: the DMA controllers the multiplexer channels feed, in order (each takes as many as it has channels)
DMA_CONTROLLERS = ("DMA1", "DMA2")
CSR, CFR = 0x80, 0x84
RG_BASE, RG_COUNT, RGSR, RGCFR = 0x100, 4, 0x140, 0x144

# CxCR fields
DMAREQ_ID_MASK = 0x7F
SOIE, EGE, SE = 1 << 8, 1 << 9, 1 << 16
CXCR_MASK = 0x1FFF_037F
# RGxCR fields
RG_GE = 1 << 16
RGCR_MASK = 0x00FF_011F

#: DMAMUX1 request inputs of the STM32G474 (RM0440 table "DMAMUX: assignment of multiplexer inputs to resources")
REQUEST_IDS: dict[str, int] = {
    "MEM2MEM": 0, "GENERATOR0": 1, "GENERATOR1": 2, "GENERATOR2": 3, "GENERATOR3": 4, "ADC1": 5,
    "DAC1_CH1": 6, "DAC1_CH2": 7, "TIM6_UP": 8, "TIM7_UP": 9, "SPI1_RX": 10, "SPI1_TX": 11, "SPI2_RX": 12,
    "SPI2_TX": 13, "SPI3_RX": 14, "SPI3_TX": 15, "I2C1_RX": 16, "I2C1_TX": 17, "I2C2_RX": 18, "I2C2_TX": 19,
    "I2C3_RX": 20, "I2C3_TX": 21, "I2C4_RX": 22, "I2C4_TX": 23, "USART1_RX": 24, "USART1_TX": 25,
    "USART2_RX": 26, "USART2_TX": 27, "USART3_RX": 28, "USART3_TX": 29, "UART4_RX": 30, "UART4_TX": 31,
    "UART5_RX": 32, "UART5_TX": 33, "LPUART1_RX": 34, "LPUART1_TX": 35, "ADC2": 36, "ADC3": 37, "ADC4": 38,
    "ADC5": 39, "QUADSPI": 40, "DAC2_CH1": 41, "TIM1_CH1": 42, "TIM1_CH2": 43, "TIM1_CH3": 44, "TIM1_CH4": 45,
    "TIM1_UP": 46, "TIM1_TRIG": 47, "TIM1_COM": 48, "TIM8_CH1": 49, "TIM8_CH2": 50, "TIM8_CH3": 51,
    "TIM8_CH4": 52, "TIM8_UP": 53, "TIM8_TRIG": 54, "TIM8_COM": 55, "TIM2_CH1": 56, "TIM2_CH2": 57,
    "TIM2_CH3": 58, "TIM2_CH4": 59, "TIM2_UP": 60, "TIM3_CH1": 61, "TIM3_CH2": 62, "TIM3_CH3": 63,
    "TIM3_CH4": 64, "TIM3_UP": 65, "TIM3_TRIG": 66, "TIM4_CH1": 67, "TIM4_CH2": 68, "TIM4_CH3": 69,
    "TIM4_CH4": 70, "TIM4_UP": 71, "TIM5_CH1": 72, "TIM5_CH2": 73, "TIM5_CH3": 74, "TIM5_CH4": 75,
    "TIM5_UP": 76, "TIM5_TRIG": 77, "TIM15_CH1": 78, "TIM15_UP": 79, "TIM15_TRIG": 80, "TIM15_COM": 81,
    "TIM16_CH1": 82, "TIM16_UP": 83, "TIM17_CH1": 84, "TIM17_UP": 85, "TIM20_CH1": 86, "TIM20_CH2": 87,
    "TIM20_CH3": 88, "TIM20_CH4": 89, "TIM20_UP": 90, "AES_IN": 91, "AES_OUT": 92, "TIM20_TRIG": 93,
    "TIM20_COM": 94, "HRTIM1_M": 95, "HRTIM1_A": 96, "HRTIM1_B": 97, "HRTIM1_C": 98, "HRTIM1_D": 99,
    "HRTIM1_E": 100, "HRTIM1_F": 101, "DAC3_CH1": 102, "DAC3_CH2": 103, "DAC4_CH1": 104, "DAC4_CH2": 105,
    "SPI4_RX": 106, "SPI4_TX": 107, "SAI1_A": 108, "SAI1_B": 109, "FMAC_WRITE": 110, "FMAC_READ": 111,
    "CORDIC_WRITE": 112, "CORDIC_READ": 113, "UCPD1_RX": 114, "UCPD1_TX": 115,
}


@register("DMAMUX1")
class Dmamux(Peripheral):
    """The request multiplexer: CxCR per channel, the status and request-generator registers stored."""

    base = 0x4002_0800
    size = 0x400

    def reset(self) -> None:
        self.cxcr = [0] * (2 * channel_count(self.bus))
        self.rgcr = [0] * RG_COUNT
        #: requests no enabled DMA channel took, by request id (count)
        self.unserved: dict[int, int] = {}

    def read(self, offset: int, size: int, now: int) -> int:
        del size, now
        if offset & 3 == 0 and offset < 4 * len(self.cxcr):
            return self.cxcr[offset // 4]
        if offset & 3 == 0 and RG_BASE <= offset < RG_BASE + 4 * RG_COUNT:
            return self.rgcr[(offset - RG_BASE) // 4]
        if offset in (CSR, CFR, RGSR, RGCFR):
            return 0  # no synchronisation overrun, no trigger overrun (neither is modelled); CFR/RGCFR write-only
        raise self._unknown(offset, "read")

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        del size, now
        if offset & 3 == 0 and offset < 4 * len(self.cxcr):
            value &= CXCR_MASK
            for bit, field in ((SE, "SE (synchronisation)"), (EGE, "EGE (event generation)")):
                if value & bit:
                    raise BoardError(f"DMAMUX1 C{offset // 4}CR: {field} is not modelled by the virtual board")
            self.cxcr[offset // 4] = value
        elif offset & 3 == 0 and RG_BASE <= offset < RG_BASE + 4 * RG_COUNT:
            if value & RG_GE:
                raise BoardError(f"DMAMUX1 RG{(offset - RG_BASE) // 4}CR: GE (request generator) is not modelled "
                                 "by the virtual board")
            self.rgcr[(offset - RG_BASE) // 4] = value & RGCR_MASK
        elif offset in (CFR, RGCFR):
            pass  # clear flags that never get set
        elif offset not in (CSR, RGSR):  # read-only
            raise self._unknown(offset, "write")

    def _unknown(self, offset: int, access: str) -> BoardError:
        return BoardError(f"{access} of DMAMUX1 at offset {offset:#05x} ({self.base + offset:#010x}), which the "
                          "virtual board does not model (CxCR, CSR, CFR, RGxCR, RGSR, RGCFR, word-aligned)")

    def route(self, mux_channel: int) -> tuple[Dma, int]:
        """The DMA controller and its 1-based channel that multiplexer channel `mux_channel` feeds."""
        first = 0
        for name in DMA_CONTROLLERS:
            dma = self.bus.peripheral(name)
            if not isinstance(dma, Dma):
                raise BoardError(f"DMAMUX1: the board's {name} is not a DMA controller")
            if mux_channel < first + len(dma.channels):
                return dma, mux_channel - first + 1
            first += len(dma.channels)
        raise BoardError(f"DMAMUX1 has no channel {mux_channel}")

    def request(self, request_id: int, now: int) -> bool:
        """Peripheral request `request_id` (REQUEST_IDS) at cycle `now`: the DMA channel it is routed to moves one
        item; False when no multiplexer channel selects it or its DMA channel does not take it (disabled, or its
        count done), which the chip would leave pending and the caller decides about (an ADC overrun, say)."""
        if request_id == 0:
            raise BoardError("DMAMUX1: request id 0 is no peripheral's request (memory-to-memory)")
        for mux_channel, cxcr in enumerate(self.cxcr):
            if cxcr & DMAREQ_ID_MASK == request_id:
                dma, channel = self.route(mux_channel)
                if dma.transfer(channel, now):
                    return True
        self.unserved[request_id] = self.unserved.get(request_id, 0) + 1
        return False


__all__ = ["REQUEST_IDS", "Dmamux"]
