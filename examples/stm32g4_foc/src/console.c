/* USART2 console (RM0440 section 37): 8N1, transmit only, blocking on TXE. */
#include "device.h"
#include "fw.h"

void console_init(uint32_t pclk_hz, uint32_t baud)
{
    RCC->AHB2ENR |= RCC_AHB2ENR_GPIOAEN;
    RCC->APB1ENR1 |= RCC_APB1ENR1_USART2EN;
    (void)RCC->APB1ENR1;
    /* PA2 TX, PA3 RX: alternate function 7 */
    GPIOA->MODER = (GPIOA->MODER & ~((3UL << 4) | (3UL << 6))) | (2UL << 4) | (2UL << 6);
    GPIOA->AFR[0] = (GPIOA->AFR[0] & ~((0xFUL << 8) | (0xFUL << 12))) | (7UL << 8) | (7UL << 12);
    USART2->CR1 = 0u;
    USART2->BRR = (pclk_hz + baud / 2u) / baud; /* oversampling by 16 */
    USART2->CR1 = USART_CR1_TE | USART_CR1_RE | USART_CR1_UE;
}

void console_write(const char *s)
{
    while (*s != '\0') {
        while ((USART2->ISR & USART_ISR_TXE_TXFNF) == 0u) {
        }
        USART2->TDR = (uint8_t)*s++;
    }
    while ((USART2->ISR & USART_ISR_TC) == 0u) {
    }
}

void console_write_u32(uint32_t v)
{
    char buf[11];
    int i = 10;
    buf[i] = '\0';
    do {
        buf[--i] = (char)('0' + (v % 10u));
        v /= 10u;
    } while (v != 0u && i > 0);
    console_write(&buf[i]);
}
