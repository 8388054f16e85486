/*
 * Clock set-up of the STM32G474 (RM0440 sections 5.3.3, 6.1.5, 7.2): HSE 24 MHz -> PLL -> SYSCLK 170 MHz in
 * voltage range 1 boost mode, with the flash wait states for it, polling every ready flag as ST's LL drivers do
 * (the sequence of firmware_stub/boards/stm32g474/stm32g474_ll.h, shared with the firmware API's board layer).
 */
#include <stdint.h>

#include "board.h"
#include "device.h"
#include "fw.h"
#include "stm32g474_ll.h"

uint32_t SystemCoreClock = 16000000u; /* HSI16 after reset */

void SystemInit(void)
{
    SCB->VTOR = FLASH_BASE; /* the vector table at the start of flash */
}

void SystemClock_Config(void)
{
    g4_clock_init(RCC_PLLCFGR_PLLSRC_HSE, BOARD_PLL_M, BOARD_PLL_N, BOARD_PLL_R);
    SystemCoreClock = BOARD_SYSCLK_HZ;
}
