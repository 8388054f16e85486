/* USART2 console (RM0440 section 37): 8N1, transmit only, blocking on TXE. */
#include "device.h"
#include "fw.h"
#include "stm32g474_ll.h"

void console_init(uint32_t pclk_hz, uint32_t baud)
{
    g4_usart2_init(pclk_hz, baud);
}

void console_write(const char *s)
{
    g4_usart2_write(s);
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
