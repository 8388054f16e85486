/*
 * Clock set-up of the STM32G474 (RM0440 sections 5.3.3, 6.1.5, 7.2): HSE 24 MHz -> PLL -> SYSCLK 170 MHz in
 * voltage range 1 boost mode, with the flash wait states for it, polling every ready flag as ST's LL drivers do.
 */
#include <stdint.h>

#include "board.h"
#include "device.h"
#include "fw.h"

uint32_t SystemCoreClock = 16000000u; /* HSI16 after reset */

void SystemInit(void)
{
    SCB->VTOR = FLASH_BASE; /* the vector table at the start of flash */
}

void SystemClock_Config(void)
{
    uint32_t i;
    /* 1. Voltage scaling: PWR clock on, range 1 (its reset value) confirmed, then boost (R1MODE = 0) */
    RCC->APB1ENR1 |= RCC_APB1ENR1_PWREN;
    (void)RCC->APB1ENR1; /* the clock is on before the first PWR access */
    PWR->CR1 = (PWR->CR1 & ~PWR_CR1_VOS) | PWR_CR1_VOS_0;
    while ((PWR->SR2 & PWR_SR2_VOSF) != 0u) {
    }
    PWR->CR5 &= ~PWR_CR5_R1MODE;
    /* 2. Flash: 4 wait states for 136..170 MHz in boost mode (RM0440 Table 9), prefetch and caches on */
    FLASH->ACR = (FLASH->ACR & ~FLASH_ACR_LATENCY) | FLASH_ACR_LATENCY_4WS | FLASH_ACR_PRFTEN | FLASH_ACR_ICEN |
                 FLASH_ACR_DCEN;
    while ((FLASH->ACR & FLASH_ACR_LATENCY) != FLASH_ACR_LATENCY_4WS) {
    }
    /* 3. HSE crystal on */
    RCC->CR |= RCC_CR_HSEON;
    while ((RCC->CR & RCC_CR_HSERDY) == 0u) {
    }
    /* 4. PLL: HSE / M * N / R = 24 MHz / 6 * 85 / 2 = 170 MHz (VCO 340 MHz) */
    RCC->CR &= ~RCC_CR_PLLON;
    while ((RCC->CR & RCC_CR_PLLRDY) != 0u) {
    }
    RCC->PLLCFGR = RCC_PLLCFGR_PLLSRC_HSE | ((BOARD_PLL_M - 1u) << RCC_PLLCFGR_PLLM_Pos) |
                   (BOARD_PLL_N << RCC_PLLCFGR_PLLN_Pos) | (((BOARD_PLL_R / 2u) - 1u) << RCC_PLLCFGR_PLLR_Pos) |
                   RCC_PLLCFGR_PLLREN;
    RCC->CR |= RCC_CR_PLLON;
    while ((RCC->CR & RCC_CR_PLLRDY) == 0u) {
    }
    /* 5. Switch to the PLL through AHB /2 for 1 us (the boost-mode transition of RM0440 6.1.5), then /1;
     *    APB1 and APB2 /1 */
    RCC->CFGR = (RCC->CFGR & ~(RCC_CFGR_HPRE | RCC_CFGR_PPRE1 | RCC_CFGR_PPRE2)) | RCC_CFGR_HPRE_DIV2;
    RCC->CFGR = (RCC->CFGR & ~RCC_CFGR_SW) | RCC_CFGR_SW_PLL;
    while ((RCC->CFGR & RCC_CFGR_SWS) != RCC_CFGR_SWS_PLL) {
    }
    for (i = 0u; i < 100u; ++i) { /* >= 1 us at 85 MHz */
        __asm volatile("nop");
    }
    RCC->CFGR = (RCC->CFGR & ~RCC_CFGR_HPRE) | RCC_CFGR_HPRE_DIV1;
    SystemCoreClock = BOARD_SYSCLK_HZ;
}
