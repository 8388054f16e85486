"""The STM32G4 parts the virtual board emulates, as data (RM0440 memory map; DS12288 for the G474, DS12589 for
the G431): memory sizes, the CCM-SRAM and its alias at the end of SRAM, the interrupt lines the models raise,
and which modelled peripherals the part has. An address of the part outside these is an unmodelled access."""

from __future__ import annotations

from dataclasses import dataclass

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError

FLASH_BASE = 0x0800_0000
SRAM_BASE = 0x2000_0000
CCM_BASE = 0x1000_0000
#: the FDCAN message RAM (RM0440 2.2.2: 0x4000A400, 212 words per controller), plain SRAM on the chip
FDCAN_RAM_BASE = 0x4000_A400

#: NVIC interrupt lines (RM0440 table 97, position after the 16 system exceptions)
IRQ = {"EXTI0": 6, "EXTI1": 7, "EXTI2": 8, "EXTI3": 9, "EXTI4": 10, "EXTI9_5": 23, "EXTI15_10": 40,
       "ADC1_2": 18, "FDCAN1_IT0": 21, "FDCAN1_IT1": 22, "TIM1_BRK_TIM15": 24, "TIM1_UP_TIM16": 25,
       "TIM1_TRG_COM_TIM17": 26, "TIM1_CC": 27, "TIM2": 28, "TIM3": 29, "TIM4": 30, "USART1": 37, "USART2": 38,
       "USART3": 39}

#: RM0440 2.2.2 register boundary addresses: names for the error of an unmodelled access
KNOWN_BLOCKS = {
    0x4000_0000: "TIM2", 0x4000_0400: "TIM3", 0x4000_0800: "TIM4", 0x4000_0C00: "TIM5", 0x4000_1000: "TIM6",
    0x4000_1400: "TIM7", 0x4000_2400: "CRS", 0x4000_2800: "TAMP", 0x4000_2C00: "WWDG", 0x4000_3000: "IWDG",
    0x4000_3800: "SPI2", 0x4000_3C00: "SPI3", 0x4000_4400: "USART2", 0x4000_4800: "USART3", 0x4000_4C00: "UART4",
    0x4000_5000: "UART5", 0x4000_5400: "I2C1", 0x4000_5800: "I2C2", 0x4000_5C00: "USB", 0x4000_6400: "FDCAN1",
    0x4000_6800: "FDCAN2", 0x4000_6C00: "FDCAN3", 0x4000_7000: "PWR", 0x4000_7400: "I2C3", 0x4000_7800: "LPTIM1",
    0x4000_8000: "LPUART1", 0x4000_8400: "I2C4", 0x4000_8800: "UCPD1", 0x4000_A400: "FDCAN message RAM",
    0x4001_0000: "SYSCFG/VREFBUF/COMP/OPAMP", 0x4001_0400: "EXTI", 0x4001_2C00: "TIM1", 0x4001_3000: "SPI1",
    0x4001_3400: "TIM8", 0x4001_3800: "USART1", 0x4001_3C00: "SPI4", 0x4001_4000: "TIM15", 0x4001_4400: "TIM16",
    0x4001_4800: "TIM17", 0x4001_5000: "TIM20", 0x4001_5400: "SAI1", 0x4001_6800: "HRTIM", 0x4002_0000: "DMA1",
    0x4002_0400: "DMA2", 0x4002_0800: "DMAMUX", 0x4002_1000: "RCC", 0x4002_2000: "FLASH", 0x4002_3000: "CRC",
    0x4002_4000: "FMAC", 0x4002_0C00: "CORDIC", 0x4800_0000: "GPIOA", 0x4800_0400: "GPIOB", 0x4800_0800: "GPIOC",
    0x4800_0C00: "GPIOD", 0x4800_1000: "GPIOE", 0x4800_1400: "GPIOF", 0x4800_1800: "GPIOG", 0x5000_0000: "ADC1/ADC2",
    0x5000_0400: "ADC3/ADC4/ADC5", 0x5000_0800: "DAC1", 0x5000_0C00: "DAC2", 0x5000_1000: "DAC3",
    0x5000_1400: "DAC4", 0x5006_0000: "AES", 0x5006_0800: "RNG", 0xA000_0000: "FMC", 0xA000_1000: "QUADSPI",
    0xE000_0000: "ITM", 0xE000_1000: "DWT", 0xE000_2000: "FPB", 0xE004_2000: "DBGMCU", 0xE00F_F000: "ROM table",
}


def block_name(address: int) -> str:
    """The RM0440 peripheral whose register block holds `address` ("unknown" outside every block)."""
    base = max((b for b in KNOWN_BLOCKS if b <= address), default=None)
    if base is None or address - base >= 0x400:
        return "unknown"
    return KNOWN_BLOCKS[base]


@dataclass(frozen=True, slots=True)
class Part:
    """One STM32G4 part: memories [bytes], the modelled peripherals it has (RM0440 names), its DBGMCU IDCODE."""

    name: str
    flash_size: int
    sram_size: int
    ccm_size: int
    peripherals: tuple[str, ...]
    idcode: int
    irq_count: int = 102

    @property
    def ccm_alias(self) -> int:
        """Where CCM-SRAM also appears: right after SRAM1 + SRAM2."""
        return SRAM_BASE + self.sram_size


_COMMON = ("RCC", "PWR", "FLASH", "GPIOA", "GPIOB", "GPIOC", "GPIOD", "GPIOE", "GPIOF", "GPIOG", "USART2", "TIM1",
           "TIM3", "TIM4", "ADC1", "ADC2", "ADC12_COMMON", "FDCAN1", "DMA1", "DMA2", "DMAMUX1", "OPAMP", "CORDIC",
           "WWDG", "IWDG", "SYSCFG", "EXTI")

PARTS = {
    "stm32g474": Part("stm32g474", flash_size=512 << 10, sram_size=96 << 10, ccm_size=32 << 10, peripherals=_COMMON,
                      idcode=0x1000_6469),
    "stm32g431": Part("stm32g431", flash_size=128 << 10, sram_size=22 << 10, ccm_size=10 << 10,
                      peripherals=_COMMON,
                      idcode=0x1000_6468),
}


def part_named(name: str) -> Part:
    """The part `name` (stm32g474, stm32g431; case-insensitive, a trailing package letter ignored)."""
    key = name.strip().lower()
    for known, part in PARTS.items():
        if key.startswith(known):
            return part
    raise BoardError(f"board part: unknown part {name!r} (known: {', '.join(PARTS)})")
