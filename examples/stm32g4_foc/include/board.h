/*
 * The board: a NUCLEO-G474RE with a three-phase inverter board (three low-side shunts, a DC-link divider, an
 * incremental encoder). What the firmware assumes of the hardware, in one place; the virtual board's description
 * (docs/firmware_api.md, "the virtual board") states the same values. Override any of them with
 * `hil fw build --define NAME=VALUE`.
 */
#ifndef FW_BOARD_H
#define FW_BOARD_H

/* Clocks: HSE crystal 24 MHz -> PLL (M 6, N 85, R 2) -> SYSCLK 170 MHz (range 1 boost); AHB, APB1, APB2 /1. */
#ifndef BOARD_HSE_HZ
#define BOARD_HSE_HZ 24000000u
#endif
#define BOARD_PLL_M 6u
#define BOARD_PLL_N 85u
#define BOARD_PLL_R 2u
#define BOARD_SYSCLK_HZ (BOARD_HSE_HZ / BOARD_PLL_M * BOARD_PLL_N / BOARD_PLL_R)

/* PWM: TIM1 centre-aligned, carrier frequency and dead time (BDTR.DTG, tDTS = 1/SYSCLK). */
#ifndef BOARD_PWM_HZ
#define BOARD_PWM_HZ 20000u
#endif
#ifndef BOARD_DEADTIME_NS
#define BOARD_DEADTIME_NS 500u
#endif

/* Analog front end: phase current i [A] -> v = BOARD_AFE_OFFSET_V + BOARD_AFE_GAIN_V_PER_A * i at the ADC pin;
 * DC link v_dc [V] -> v_dc * BOARD_VDC_DIVIDER; 12-bit ADC on BOARD_VREF_V. */
#ifndef BOARD_VREF_V
#define BOARD_VREF_V 3.3f
#endif
#ifndef BOARD_AFE_OFFSET_V
#define BOARD_AFE_OFFSET_V 1.65f
#endif
#ifndef BOARD_AFE_GAIN_V_PER_A
#define BOARD_AFE_GAIN_V_PER_A 0.05f
#endif
#ifndef BOARD_VDC_DIVIDER
#define BOARD_VDC_DIVIDER 0.008f /* 1/125: 412 V full scale */
#endif

/* ADC channels (ADC12_IN1 = PA0: phase a on ADC1; ADC12_IN2 = PA1: phase b on ADC2; ADC1_IN12 = PB1: DC link). */
#define BOARD_ADC_CH_IA 1u
#define BOARD_ADC_CH_IB 2u
#define BOARD_ADC_CH_VDC 12u

/* Encoder on TIM3 (CH1 = PB4, CH2 = PB5, AF2), x4 decoding; counts up with positive (counter-clockwise) rotation,
 * 0 at the electrical angle BOARD_ENCODER_OFFSET_RAD. */
#ifndef BOARD_ENCODER_LINES
#define BOARD_ENCODER_LINES 2048u
#endif
#ifndef BOARD_ENCODER_OFFSET_RAD
#define BOARD_ENCODER_OFFSET_RAD 0.0f
#endif

/* Console USART2 (PA2 TX, PA3 RX, AF7: the NUCLEO's ST-LINK virtual COM port). */
#define BOARD_CONSOLE_BAUD 115200u

/* FDCAN1 (PA11 RX, PA12 TX, AF9), kernel clock HSE: 500 kbit/s nominal, 2 Mbit/s data phase. */
#define BOARD_CAN_NOMINAL_BPS 500000u
#define BOARD_CAN_DATA_BPS 2000000u

/* Gate-driver enable: PC6, push-pull output, high = gates enabled. */
#define BOARD_ENABLE_PORT GPIOC
#define BOARD_ENABLE_PIN 6u

#endif /* FW_BOARD_H */
