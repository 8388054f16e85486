/*
 * STM32G474 register sequences that every firmware for the chip writes the same way, shared by the firmware API's
 * board layer (startup.c, board.c, fdcan.c) and board firmware that owns its peripherals (examples/stm32g4_foc): the
 * reset handler's first steps, the clock tree to 170 MHz, the USART2 console, and the FDCAN1 pins, message RAM and
 * initialisation handshake.
 * Include the register definitions first (stm32g474_regs.h, or ST's stm32g474xx.h with CMSIS).
 */
#ifndef HIL_STM32G474_LL_H
#define HIL_STM32G474_LL_H

#include <stdint.h>

/* The sections of stm32g474.ld that the reset handler initialises. */
extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss;
extern uint32_t _siccmdata, _sccmdata, _eccmdata, _sccmbss, _eccmbss;

static inline void g4_copy_words(uint32_t *dst, const uint32_t *src, const uint32_t *end)
{
    while (dst < end) {
        *dst++ = *src++;
    }
}

static inline void g4_zero_words(uint32_t *dst, const uint32_t *end)
{
    while (dst < end) {
        *dst++ = 0u;
    }
}

/* The reset handler's first steps, before any C that may use the FPU or static data: CP10, CP11 full access (the
 * single-precision FPU), .data and .ccmdata copied from flash, .bss and .ccmbss zeroed. */
static inline void g4_reset_init(void)
{
    SCB->CPACR |= (3UL << 20) | (3UL << 22);
    __DSB();
    __ISB();
    g4_copy_words(&_sdata, &_sidata, &_edata);
    g4_zero_words(&_sbss, &_ebss);
    g4_copy_words(&_sccmdata, &_siccmdata, &_eccmdata);
    g4_zero_words(&_sccmbss, &_eccmbss);
}

/* RM0440 sections 5.3.3, 6.1.5, 7.2: voltage range 1 boost, 4 flash wait states with prefetch and caches, the PLL
 * (source RCC_PLLCFGR_PLLSRC_HSE or _HSI, input / pll_m * pll_n / pll_r, R output on; the HSE crystal switched on
 * first when it is the source), then SYSCLK from the PLL through AHB /2 for >= 1 us (the boost-mode transition),
 * AHB, APB1 and APB2 /1. Every ready flag polled without a timeout, as ST's LL drivers do. */
static inline void g4_clock_init(uint32_t pll_src, uint32_t pll_m, uint32_t pll_n, uint32_t pll_r)
{
    uint32_t i;
    RCC->APB1ENR1 |= RCC_APB1ENR1_PWREN;
    (void)RCC->APB1ENR1; /* the clock is on before the first PWR access */
    PWR->CR1 = (PWR->CR1 & ~PWR_CR1_VOS) | PWR_CR1_VOS_0;
    while ((PWR->SR2 & PWR_SR2_VOSF) != 0u) {
    }
    PWR->CR5 &= ~PWR_CR5_R1MODE;
    FLASH->ACR = (FLASH->ACR & ~FLASH_ACR_LATENCY) | FLASH_ACR_LATENCY_4WS | FLASH_ACR_PRFTEN | FLASH_ACR_ICEN |
                 FLASH_ACR_DCEN;
    while ((FLASH->ACR & FLASH_ACR_LATENCY) != FLASH_ACR_LATENCY_4WS) {
    }
    if (pll_src == RCC_PLLCFGR_PLLSRC_HSE) {
        RCC->CR |= RCC_CR_HSEON;
        while ((RCC->CR & RCC_CR_HSERDY) == 0u) {
        }
    }
    RCC->CR &= ~RCC_CR_PLLON;
    while ((RCC->CR & RCC_CR_PLLRDY) != 0u) {
    }
    RCC->PLLCFGR = pll_src | ((pll_m - 1u) << RCC_PLLCFGR_PLLM_Pos) | (pll_n << RCC_PLLCFGR_PLLN_Pos) |
                   (((pll_r / 2u) - 1u) << RCC_PLLCFGR_PLLR_Pos) | RCC_PLLCFGR_PLLREN;
    RCC->CR |= RCC_CR_PLLON;
    while ((RCC->CR & RCC_CR_PLLRDY) == 0u) {
    }
    RCC->CFGR = (RCC->CFGR & ~(RCC_CFGR_HPRE | RCC_CFGR_PPRE1 | RCC_CFGR_PPRE2)) | RCC_CFGR_HPRE_DIV2;
    RCC->CFGR = (RCC->CFGR & ~RCC_CFGR_SW) | RCC_CFGR_SW_PLL;
    while ((RCC->CFGR & RCC_CFGR_SWS) != RCC_CFGR_SWS_PLL) {
    }
    for (i = 0u; i < 100u; ++i) { /* >= 1 us at 85 MHz */
        __asm__ volatile("nop");
    }
    RCC->CFGR = (RCC->CFGR & ~RCC_CFGR_HPRE) | RCC_CFGR_HPRE_DIV1;
}

/* USART2 (RM0440 section 37) on PA2 TX / PA3 RX (alternate function 7), kernel clock PCLK1 (CCIPR USART2SEL 00,
 * its reset value) of pclk_hz: 8N1 at baud, oversampling by 16. */
static inline void g4_usart2_init(uint32_t pclk_hz, uint32_t baud)
{
    RCC->AHB2ENR |= RCC_AHB2ENR_GPIOAEN;
    RCC->APB1ENR1 |= RCC_APB1ENR1_USART2EN;
    (void)RCC->APB1ENR1;
    GPIOA->MODER = (GPIOA->MODER & ~((3UL << 4) | (3UL << 6))) | (2UL << 4) | (2UL << 6);
    GPIOA->AFR[0] = (GPIOA->AFR[0] & ~((0xFUL << 8) | (0xFUL << 12))) | (7UL << 8) | (7UL << 12);
    USART2->CR1 = 0u;
    USART2->BRR = (pclk_hz + baud / 2u) / baud;
    USART2->CR1 = USART_CR1_TE | USART_CR1_RE | USART_CR1_UE;
}

/* Write a string on USART2, blocking on TXE, and wait until the last character has left (TC). */
static inline void g4_usart2_write(const char *s)
{
    while (*s != '\0') {
        while ((USART2->ISR & USART_ISR_TXE_TXFNF) == 0u) {
        }
        USART2->TDR = (uint8_t)*s++;
    }
    while ((USART2->ISR & USART_ISR_TC) == 0u) {
    }
}

/* FDCAN1's bus clock and its pins PA11 RX, PA12 TX (alternate function 9); the kernel clock (CCIPR FDCANSEL) is
 * the caller's choice. */
static inline void g4_fdcan1_pins(void)
{
    RCC->APB1ENR1 |= RCC_APB1ENR1_FDCANEN;
    RCC->AHB2ENR |= RCC_AHB2ENR_GPIOAEN;
    (void)RCC->APB1ENR1;
    GPIOA->MODER = (GPIOA->MODER & ~((3UL << 22) | (3UL << 24))) | (2UL << 22) | (2UL << 24);
    GPIOA->AFR[1] = (GPIOA->AFR[1] & ~((0xFUL << 12) | (0xFUL << 16))) | (9UL << 12) | (9UL << 16);
}

/* Wait until FDCAN1's CCCR.INIT reads `want` (FDCAN_CCCR_INIT or 0): 0, or -1 after `polls` reads. */
static inline int g4_fdcan1_wait_init(uint32_t want, uint32_t polls)
{
    uint32_t n;
    for (n = 0u; n < polls; ++n) {
        if ((FDCAN1->CCCR & FDCAN_CCCR_INIT) == want) {
            return 0;
        }
    }
    return -1;
}

/* FDCAN1's message RAM (RM0440 44.3.3, the G4's fixed layout at SRAMCAN_BASE): 28 standard filters, 8 extended
 * filters, RX FIFO 0 and 1 of 3 elements, 3 TX event elements, 3 TX buffers; RX/TX elements of 18 words (2 header
 * words + 64 data bytes). Offsets [bytes]. */
#define G4_MRAM_FLS 0x000u     /* standard filters */
#define G4_MRAM_RF0 0x0B0u     /* RX FIFO 0 */
#define G4_MRAM_TXB 0x278u     /* TX buffers */
#define G4_MRAM_SIZE 0x350u    /* the whole of FDCAN1's message RAM */
#define G4_MRAM_ELEMENT 72u    /* bytes per RX/TX element */

/* A word of the FDCAN message RAM (RM0440 44.3.3: the G4's fixed layout at SRAMCAN_BASE), by byte offset. */
static inline volatile uint32_t *g4_mram(uint32_t offset)
{
    return (volatile uint32_t *)(SRAMCAN_BASE + offset);
}

/* Data bytes of a DLC code (CAN FD: 0..8, 12, 16, 20, 24, 32, 48, 64). */
static inline uint8_t g4_fdcan_dlc_bytes(uint32_t dlc)
{
    static const uint8_t len[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64};
    return len[dlc & 0xFu];
}

/* The oldest element of RX FIFO 0 (RM0440 44.3.3): its header words, data length [bytes], data (as words) and
 * index; the caller frees it (FDCAN1->RXF0A = get) once it has read what else it wants of the FIFO's status. */
typedef struct {
    uint32_t r0;        /* ESI, XTD, RTR, the id (a standard id in bits 28:18) */
    uint32_t r1;        /* ANMF, FIDX, FDF (bit 21), BRS, DLC (bits 19:16), RXTS */
    uint8_t len;        /* data bytes of the DLC */
    uint32_t get;       /* the element's index (F0GI) */
    uint32_t words[16]; /* the data */
} g4_fdcan_rx_t;

/* Read the oldest element of FDCAN1's RX FIFO 0 (its fill level F0FL is above 0) into `e`. */
static inline void g4_fdcan1_rx0_read(g4_fdcan_rx_t *e)
{
    uint32_t base;
    uint32_t i;
    e->get = (FDCAN1->RXF0S & FDCAN_RXF0S_F0GI) >> FDCAN_RXF0S_F0GI_Pos;
    base = G4_MRAM_RF0 + e->get * G4_MRAM_ELEMENT;
    e->r0 = *g4_mram(base);
    e->r1 = *g4_mram(base + 4u);
    e->len = g4_fdcan_dlc_bytes(e->r1 >> 16);
    for (i = 0u; i < ((uint32_t)e->len + 3u) / 4u; ++i) {
        e->words[i] = *g4_mram(base + 8u + 4u * i);
    }
}

/* The smallest DLC code that carries n data bytes. */
static inline uint32_t g4_fdcan_bytes_dlc(uint8_t n)
{
    uint32_t dlc = 0u;
    while (dlc < 15u && g4_fdcan_dlc_bytes(dlc) < n) {
        ++dlc;
    }
    return dlc;
}

#endif
