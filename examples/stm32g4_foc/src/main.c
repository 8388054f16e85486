/*
 * Field-oriented control of a PMSM on a NUCLEO-G474RE with an inverter board, register level, interrupt driven:
 *
 *   TIM1   centre-aligned PWM at BOARD_PWM_HZ (ARR = SYSCLK / (2 f)), complementary outputs with BDTR dead
 *          time, CCR1..3 preloaded, RCR = 1 so the update event (the compare values taking effect) is at the
 *          carrier valley; channel 4 in PWM mode 2 one tick before the peak drives TRGO2 (OC4REF).
 *   ADC1/2 injected conversions on TIM1 TRGO2 (the carrier peak: the middle of the zero vector, where the phase
 *          currents equal their period mean): ADC1 phase a then the DC link, ADC2 phase b. ADC1's end of
 *          injected sequence runs the current loop (ADC1_2_IRQHandler, priority 0), which writes CCR1..3
 *          before the next valley: they apply over the next carrier period.
 *   TIM3   encoder mode (x4) on the rotor: the angle for Park, and a PLL for the speed.
 *   SysTick 1 kHz: the speed loop (priority 1).
 *   FDCAN1 Setpoint / ConfigParam in the project's DBC (can_link.c, priority 2); without a bus the compile-time
 *          setpoint of motor.h.
 *   USART2 console: one boot line, one fault line.
 *
 * Variants (hil fw build --define NAME): LATE_ISR -- the current loop runs LATE_ISR_WORK (default 1000) steps of
 * extra work (about 30 us) before writing the compare values, past the valley, so they land one period late; FAULT -- after FAULT_AT_ISR
 * current-loop runs the ISR reads through a stale pointer into reserved address space (a precise bus fault).
 */
#include <math.h>
#include <stdint.h>

#include "board.h"
#include "device.h"
#include "foc_math.h"
#include "fw.h"
#include "motor.h"

#define PWM_ARR (BOARD_SYSCLK_HZ / (2u * BOARD_PWM_HZ))
#define TS_S (1.0f / (float)BOARD_PWM_HZ)
#define SPEED_TS_S 0.001f
#define ENCODER_COUNTS (4u * BOARD_ENCODER_LINES)
#define DEADTIME_TICKS ((BOARD_DEADTIME_NS * (BOARD_SYSCLK_HZ / 1000000u) + 500u) / 1000u)
#define ADC_FULL_SCALE 4096.0f
#define OFFSET_SAMPLES 64u
#define OFFSET_TOLERANCE 205.0f /* counts: 10 % of the full scale around the front end's nominal offset */
#define COARSE_SPAN 32u /* periods of the coarse encoder speed that starts the PLL (flying start) */
#define CONTROLLER_OFF 0u
#define CONTROLLER_EXTERNAL 255u

#if DEADTIME_TICKS > 127u
#error "BOARD_DEADTIME_NS: this firmware encodes dead times up to 127 ticks (DTG[7] = 0, RM0440 28.6.20)"
#endif
#if PWM_ARR > 65535u
#error "BOARD_PWM_HZ too low for a 16-bit TIM1 period at PSC = 0"
#endif

#if defined(LATE_ISR) && !defined(LATE_ISR_WORK)
#define LATE_ISR_WORK 1000u /* filter steps: about 5000 cycles, 30 us at 170 MHz (CPI 1) */
#endif
#if defined(FAULT) && !defined(FAULT_AT_ISR)
#define FAULT_AT_ISR 2000u
#endif
#ifndef FAULT_ADDRESS
#define FAULT_ADDRESS 0x20020000u /* past SRAM1 + SRAM2 + the CCM-SRAM alias: reserved (RM0440 Table 3) */
#endif

#if defined(FW_NO_CCM)
#define FW_CCM
#else
#define FW_CCM __attribute__((section(".ccmbss")))
#endif

/* Run-time parameters: the compile-time machine of motor.h until a ConfigParam replaces a value. */
typedef struct {
    float speed_kp, speed_ki, torque_limit, torque_init, current_limit;
    float current_kp, current_ki; /* 0: derived from the bandwidth */
} fw_params_t;

/* Control state: in the CCM SRAM (zero wait states, like the code's data on a real G4 drive). */
static struct {
    foc_params_t fp;
    foc_state_t foc;
    foc_pll_t pll;
    foc_pi_t speed_pi;
    float iq_ref;          /* A, written by the speed loop */
    float omega_m;         /* rad/s, the PLL's speed */
    float theta_e;         /* rad */
    float vdc;             /* V */
    float ia, ib;          /* A */
    float off_a, off_b;    /* ADC counts */
    uint32_t off_acc_a, off_acc_b, off_n, off_retries;
    uint32_t isr_count;
    uint32_t isr_cycles_max;
    uint32_t adc2_late;    /* ADC2's conversion not finished when ADC1's sequence ended */
    uint32_t ms;
    uint16_t counts[COARSE_SPAN]; /* the encoder count of the last COARSE_SPAN periods, a ring */
    uint32_t count_idx;
} g FW_CCM;

static fw_params_t prm = {FW_SPEED_KP, FW_SPEED_KI, FW_TORQUE_LIMIT_NM, 0.0f, FW_CURRENT_LIMIT_A, 0.0f, 0.0f};
static volatile fw_setpoint_t sp = {0u, 0u, 0.0f, CONTROLLER_OFF};
static volatile uint8_t running;
#if defined(LATE_ISR)
static volatile float late_sink;
#endif
static volatile uint8_t offsets_ready;
static uint8_t bus_ok;
volatile uint32_t fw_fault_exception;
volatile uint32_t fw_fault_cfsr;

static float clampf(float x, float lim)
{
    return x > lim ? lim : (x < -lim ? -lim : x);
}

static void gate_enable(int on)
{
    BOARD_ENABLE_PORT->BSRR = on ? (1UL << BOARD_ENABLE_PIN) : (1UL << (BOARD_ENABLE_PIN + 16u));
}

static void update_current_gains(void)
{
    foc_params_set_bandwidth(&g.fp, FW_CURRENT_BW_RAD_S);
    if (prm.current_kp > 0.0f) {
        g.fp.kp_d = prm.current_kp;
        g.fp.kp_q = prm.current_kp;
    }
    if (prm.current_ki > 0.0f) {
        g.fp.ki_d = prm.current_ki;
        g.fp.ki_q = prm.current_ki;
    }
}

uint8_t fw_running(void)
{
    return running;
}

/* ConfigParam (docs/protocol.md): the machine and the loop settings; ids this firmware does not use are
 * acknowledged; values it cannot run with are refused. Runs in the FDCAN interrupt: the current loop reads the
 * values it changes between two of its runs, each a single aligned word store. */
int fw_config(uint8_t param_id, float value)
{
    if (!isfinite(value)) {
        return -1;
    }
    switch (param_id) {
    case 1: /* rs */
        if (value < 0.0f) {
            return -1;
        }
        g.fp.rs = value;
        break;
    case 2: /* ld */
    case 3: /* lq */
    case 4: /* psi_f */
    case 5: /* pole_pairs */
        if (value <= 0.0f) {
            return -1;
        }
        if (param_id == 2u) {
            g.fp.ld = value;
        } else if (param_id == 3u) {
            g.fp.lq = value;
        } else if (param_id == 4u) {
            g.fp.psi_f = value;
        } else {
            g.fp.pole_pairs = value;
        }
        break;
#if defined(FW_BUS_SPEED_GAINS)
    case 8:
        prm.speed_kp = value;
        break;
    case 9:
        prm.speed_ki = value;
        break;
#endif
    case 10:
        if (value <= 0.0f) {
            return -1;
        }
        prm.torque_limit = value;
        break;
    case 11:
        prm.torque_init = value;
        break;
    case 18:
        prm.current_kp = value;
        break;
    case 19:
        prm.current_ki = value;
        break;
    case 22:
        if (value <= 0.0f) {
            return -1;
        }
        prm.current_limit = value;
        break;
    default: /* ts (the PWM timer sets the period), vdc (measured), the speed gains (its own, motor.h), and the
              * others: not used here */
        break;
    }
    if (param_id <= 3u || param_id == 18u || param_id == 19u) {
        update_current_gains();
    }
    return 0;
}

/* The speed over the last COARSE_SPAN periods from the encoder counts [rad/s mechanical]: a drive enabled on a
 * turning rotor starts its PLL (and so its decoupling and speed loop) at the speed instead of at rest. */
static float coarse_speed(void)
{
    const uint32_t newest = g.counts[(g.count_idx + COARSE_SPAN - 1u) % COARSE_SPAN];
    const uint32_t oldest = g.counts[g.count_idx % COARSE_SPAN];
    int32_t d = (int32_t)newest - (int32_t)oldest;
    if (d > (int32_t)(ENCODER_COUNTS / 2u)) {
        d -= (int32_t)ENCODER_COUNTS;
    } else if (d < -(int32_t)(ENCODER_COUNTS / 2u)) {
        d += (int32_t)ENCODER_COUNTS;
    }
    return (float)d * (FOC_TWO_PI / (float)ENCODER_COUNTS) / ((float)(COARSE_SPAN - 1u) * TS_S);
}

static void start_drive(void)
{
    const float w = coarse_speed();
    g.pll.integ = w;
    g.pll.omega = w;
    g.pll.theta = (float)(TIM3->CNT % ENCODER_COUNTS) * (FOC_TWO_PI / (float)ENCODER_COUNTS);
    g.omega_m = w;
    foc_reset(&g.foc, MOTOR_VDC_NOMINAL_V / FOC_SQRT3);
    g.speed_pi.integ = prm.torque_init; /* bumpless start at the expected load */
    g.iq_ref = 0.0f;
    running = 1u;
    gate_enable(1);
    TIM1->BDTR |= TIM_BDTR_MOE;
}

static void stop_drive(void)
{
    TIM1->BDTR &= ~TIM_BDTR_MOE; /* outputs to their idle level: every switch off */
    gate_enable(0);
    running = 0u;
}

/* Setpoint: 0 ok; 6 a controller id this firmware is not (FaultTarget not_implemented); 5 a bad mode or a
 * non-finite reference (FaultTarget invalid_config). */
int fw_apply_setpoint(const fw_setpoint_t *s)
{
    if (s->controller_id != CONTROLLER_EXTERNAL && s->controller_id != CONTROLLER_OFF) {
        stop_drive();
        sp.enable = 0u;
        return 6;
    }
    if (s->mode > 1u || !isfinite(s->reference)) {
        stop_drive();
        sp.enable = 0u;
        return 5;
    }
    __disable_irq();
    sp.mode = s->mode;
    sp.reference = s->reference;
    sp.controller_id = s->controller_id;
    sp.enable = s->enable;
    __enable_irq();
    if (s->enable != 0u && running == 0u && offsets_ready != 0u) {
        start_drive();
    } else if (s->enable == 0u && running != 0u) {
        stop_drive();
    }
    return 0;
}

/* ---- peripherals ---- */

static void gpio_init(void)
{
    RCC->AHB2ENR |= RCC_AHB2ENR_GPIOAEN | RCC_AHB2ENR_GPIOBEN | RCC_AHB2ENR_GPIOCEN;
    (void)RCC->AHB2ENR;
    /* gate enable: output, low */
    gate_enable(0);
    BOARD_ENABLE_PORT->MODER = (BOARD_ENABLE_PORT->MODER & ~(3UL << (2u * BOARD_ENABLE_PIN))) |
                               (1UL << (2u * BOARD_ENABLE_PIN));
    /* TIM1 CH1..3 on PA8..PA10 (AF6) */
    GPIOA->MODER = (GPIOA->MODER & ~((3UL << 16) | (3UL << 18) | (3UL << 20))) | (2UL << 16) | (2UL << 18) |
                   (2UL << 20);
    GPIOA->AFR[1] = (GPIOA->AFR[1] & ~0xFFFUL) | (6UL << 0) | (6UL << 4) | (6UL << 8);
    /* TIM1 CH1N, CH2N on PB13, PB14 (AF6), CH3N on PB15 (AF4); TIM3 CH1, CH2 on PB4, PB5 (AF2) */
    GPIOB->MODER = (GPIOB->MODER & ~((3UL << 26) | (3UL << 28) | (3UL << 30) | (3UL << 8) | (3UL << 10))) |
                   (2UL << 26) | (2UL << 28) | (2UL << 30) | (2UL << 8) | (2UL << 10);
    GPIOB->AFR[1] = (GPIOB->AFR[1] & ~(0xFFFUL << 20)) | (6UL << 20) | (6UL << 24) | (4UL << 28);
    GPIOB->AFR[0] = (GPIOB->AFR[0] & ~(0xFFUL << 16)) | (2UL << 16) | (2UL << 20);
    /* analog inputs: PA0, PA1, PB1 */
    GPIOA->MODER |= (3UL << 0) | (3UL << 2);
    GPIOB->MODER |= (3UL << 2);
}

static void encoder_init(void)
{
    RCC->APB1ENR1 |= RCC_APB1ENR1_TIM3EN;
    (void)RCC->APB1ENR1;
    TIM3->CR1 = 0u;
    TIM3->SMCR = 3UL << TIM_SMCR_SMS_Pos;                  /* encoder mode 3: both edges of TI1 and TI2 */
    TIM3->CCMR1 = TIM_CCMR1_CC1S_0 | TIM_CCMR1_CC2S_0 |    /* IC1 on TI1, IC2 on TI2 */
                  (2UL << TIM_CCMR1_IC1F_Pos) | (2UL << TIM_CCMR1_IC2F_Pos);
    TIM3->CCER = 0u;                                       /* both polarities non-inverted */
    TIM3->ARR = ENCODER_COUNTS - 1u;                       /* one mechanical turn */
    TIM3->CNT = 0u;
    TIM3->CR1 = TIM_CR1_CEN;
}

static void pwm_init(void)
{
    RCC->APB2ENR |= RCC_APB2ENR_TIM1EN;
    (void)RCC->APB2ENR;
    TIM1->CR1 = TIM_CR1_CMS_0 | TIM_CR1_ARPE; /* centre-aligned mode 1, ARR preloaded, stopped */
    TIM1->CR2 = 7UL << TIM_CR2_MMS2_Pos;      /* TRGO2 = OC4REFC */
    TIM1->PSC = 0u;
    TIM1->ARR = PWM_ARR;
    TIM1->RCR = 1u; /* one update every other overflow/underflow: at the valley (loaded by the UG below) */
    TIM1->CCMR1 = (6UL << TIM_CCMR1_OC1M_Pos) | TIM_CCMR1_OC1PE | (6UL << TIM_CCMR1_OC2M_Pos) | TIM_CCMR1_OC2PE;
    TIM1->CCMR2 = (6UL << TIM_CCMR2_OC3M_Pos) | TIM_CCMR2_OC3PE | (7UL << TIM_CCMR2_OC4M_Pos) | TIM_CCMR2_OC4PE;
    TIM1->CCR1 = PWM_ARR / 2u;
    TIM1->CCR2 = PWM_ARR / 2u;
    TIM1->CCR3 = PWM_ARR / 2u;
    TIM1->CCR4 = PWM_ARR - 1u; /* OC4REF (PWM mode 2) rises one tick before the peak */
    TIM1->CCER = TIM_CCER_CC1E | TIM_CCER_CC1NE | TIM_CCER_CC2E | TIM_CCER_CC2NE | TIM_CCER_CC3E | TIM_CCER_CC3NE;
    TIM1->BDTR = (DEADTIME_TICKS << TIM_BDTR_DTG_Pos) | TIM_BDTR_OSSR | TIM_BDTR_OSSI; /* MOE off */
    TIM1->EGR = TIM_EGR_UG; /* load PSC, ARR, RCR (repetition counter = 1) and the compare preloads */
    TIM1->SR = 0u;
}

static void delay_cycles(uint32_t cycles)
{
    const uint32_t t0 = DWT->CYCCNT;
    while (DWT->CYCCNT - t0 < cycles) {
    }
}

static void adc_enable(ADC_TypeDef *adc)
{
    adc->CR = 0u;                  /* leave deep power-down */
    adc->CR = ADC_CR_ADVREGEN;     /* voltage regulator on, then tADCVREG_STUP = 20 us */
    delay_cycles(20u * (BOARD_SYSCLK_HZ / 1000000u));
    adc->CR &= ~ADC_CR_ADCALDIF;   /* single-ended calibration */
    adc->CR |= ADC_CR_ADCAL;
    while ((adc->CR & ADC_CR_ADCAL) != 0u) {
    }
    delay_cycles(4u * 4u);         /* 4 ADC clocks between the end of calibration and ADEN */
    adc->ISR = ADC_ISR_ADRDY;
    adc->CR |= ADC_CR_ADEN;
    while ((adc->ISR & ADC_ISR_ADRDY) == 0u) {
    }
    adc->ISR = ADC_ISR_ADRDY;
}

static void adc_init(void)
{
    const uint32_t jext = (8UL << ADC_JSQR_JEXTSEL_Pos) | (1UL << ADC_JSQR_JEXTEN_Pos); /* TIM1_TRGO2, rising */
    RCC->AHB2ENR |= RCC_AHB2ENR_ADC12EN;
    (void)RCC->AHB2ENR;
    ADC12_COMMON->CCR = (ADC12_COMMON->CCR & ~ADC_CCR_CKMODE) | (3UL << ADC_CCR_CKMODE_Pos); /* HCLK/4 */
    adc_enable(ADC1);
    adc_enable(ADC2);
    /* 12.5 ADC clock cycles of sampling on every channel used */
    ADC1->SMPR1 = (2UL << ADC_SMPR1_SMP1_Pos);
    ADC1->SMPR2 = (2UL << ADC_SMPR2_SMP12_Pos);
    ADC2->SMPR1 = (2UL << ADC_SMPR1_SMP2_Pos);
    ADC1->JSQR = (1UL << ADC_JSQR_JL_Pos) | jext | (BOARD_ADC_CH_IA << ADC_JSQR_JSQ1_Pos) |
                 (BOARD_ADC_CH_VDC << ADC_JSQR_JSQ2_Pos);
    ADC2->JSQR = (0UL << ADC_JSQR_JL_Pos) | jext | (BOARD_ADC_CH_IB << ADC_JSQR_JSQ1_Pos);
    ADC1->IER = ADC_IER_JEOSIE;
    ADC1->CR |= ADC_CR_JADSTART; /* armed: each trigger converts the injected sequence */
    ADC2->CR |= ADC_CR_JADSTART;
}

/* ---- interrupts ---- */

void ADC1_2_IRQHandler(void)
{
    const uint32_t t0 = DWT->CYCCNT;
    const float k_i = BOARD_VREF_V / ADC_FULL_SCALE / BOARD_AFE_GAIN_V_PER_A;
    uint32_t raw_a;
    uint32_t raw_b;
    uint32_t raw_vdc;
    uint32_t dt;
    uint32_t cnt;
    float duty[3];
    float theta_m;
    if ((ADC1->ISR & ADC_ISR_JEOS) == 0u) {
        return;
    }
    if ((ADC2->ISR & ADC_ISR_JEOS) == 0u) {
        g.adc2_late++;
    }
    ADC1->ISR = ADC_ISR_JEOS | ADC_ISR_JEOC;
    ADC2->ISR = ADC_ISR_JEOS | ADC_ISR_JEOC;
    raw_a = ADC1->JDR1;
    raw_vdc = ADC1->JDR2;
    raw_b = ADC2->JDR1;
    g.isr_count++;
#if defined(FAULT)
    if (g.isr_count == FAULT_AT_ISR) {
        /* the bug: a calibration pointer never set, read in the ISR */
        const volatile uint32_t *stale = (const volatile uint32_t *)FAULT_ADDRESS;
        raw_a += *stale;
    }
#endif
    if (offsets_ready == 0u) {
        g.counts[g.count_idx % COARSE_SPAN] = (uint16_t)TIM3->CNT;
        g.count_idx++;
        g.off_acc_a += raw_a;
        g.off_acc_b += raw_b;
        if (++g.off_n == OFFSET_SAMPLES) {
            const float nominal = BOARD_AFE_OFFSET_V / BOARD_VREF_V * ADC_FULL_SCALE;
            g.off_a = (float)g.off_acc_a / (float)OFFSET_SAMPLES;
            g.off_b = (float)g.off_acc_b / (float)OFFSET_SAMPLES;
            g.off_acc_a = 0u;
            g.off_acc_b = 0u;
            g.off_n = 0u;
            if (fabsf(g.off_a - nominal) < OFFSET_TOLERANCE && fabsf(g.off_b - nominal) < OFFSET_TOLERANCE) {
                offsets_ready = 1u;
            } else {
                g.off_retries++; /* an amplifier not settled (or not powered): measure again */
            }
        }
        return;
    }
    g.ia = ((float)raw_a - g.off_a) * k_i;
    g.ib = ((float)raw_b - g.off_b) * k_i;
    g.vdc = (float)raw_vdc * (BOARD_VREF_V / ADC_FULL_SCALE / BOARD_VDC_DIVIDER);
    cnt = TIM3->CNT;
    g.counts[g.count_idx % COARSE_SPAN] = (uint16_t)cnt;
    g.count_idx++;
    theta_m = (float)cnt * (FOC_TWO_PI / (float)ENCODER_COUNTS);
    g.omega_m = foc_pll_step(&g.pll, theta_m, TS_S);
    g.theta_e = foc_wrap_2pi(g.fp.pole_pairs * theta_m + BOARD_ENCODER_OFFSET_RAD);
    if (running == 0u) {
        return;
    }
    foc_current_step(&g.foc, &g.fp, g.ia, g.ib, g.theta_e, g.fp.pole_pairs * g.omega_m,
                     g.vdc > 1.0f ? g.vdc : MOTOR_VDC_NOMINAL_V, 0.0f, g.iq_ref, duty);
#if defined(LATE_ISR)
    { /* the bug: work that does not fit between the peak and the valley (a diagnostic filter bank run in the
       * current loop), done before the compare values are written */
        uint32_t n;
        float acc = late_sink;
        for (n = 0u; n < LATE_ISR_WORK; ++n) {
            acc = 0.999f * acc + 0.001f * g.foc.iq;
        }
        late_sink = acc;
    }
#endif
    TIM1->CCR1 = (uint32_t)(duty[0] * (float)PWM_ARR + 0.5f);
    TIM1->CCR2 = (uint32_t)(duty[1] * (float)PWM_ARR + 0.5f);
    TIM1->CCR3 = (uint32_t)(duty[2] * (float)PWM_ARR + 0.5f);
    dt = DWT->CYCCNT - t0;
    if (dt > g.isr_cycles_max) {
        g.isr_cycles_max = dt;
    }
}

void SysTick_Handler(void)
{
    float torque;
    g.ms++;
    if (bus_ok != 0u && sp.enable == 0u && running == 0u && can_frames_received() == 0u &&
        g.ms == FW_BUS_SILENT_MS) {
        /* a bus that stays silent: run the compile-time setpoint */
        const fw_setpoint_t dflt = {1u, 0u, FW_DEFAULT_SPEED_RPM * (FOC_TWO_PI / 60.0f), CONTROLLER_EXTERNAL};
        prm.torque_init = FW_DEFAULT_TORQUE_INIT_NM;
        (void)fw_apply_setpoint(&dflt);
    }
    if (running == 0u && sp.enable != 0u && offsets_ready != 0u) {
        start_drive(); /* enabled before the current offsets were measured */
    }
    if (running == 0u) {
        return;
    }
    g.speed_pi.kp = prm.speed_kp;
    g.speed_pi.ki = prm.speed_ki;
    g.speed_pi.limit = prm.torque_limit;
    if (sp.mode == 0u) {
        torque = foc_pi_step(&g.speed_pi, sp.reference - g.omega_m, SPEED_TS_S);
    } else {
        torque = clampf(sp.reference, prm.torque_limit);
    }
    g.iq_ref = clampf(torque / (1.5f * g.fp.pole_pairs * g.fp.psi_f), prm.current_limit);
}

void fw_fault_stop(uint32_t exception)
{
    TIM1->BDTR &= ~TIM_BDTR_MOE;
    gate_enable(0);
    fw_fault_exception = exception;
    fw_fault_cfsr = SCB->CFSR;
    console_write("FAULT exception ");
    console_write_u32(exception);
    console_write(" cfsr ");
    console_write_u32(fw_fault_cfsr);
    console_write("\r\n");
    __disable_irq();
    for (;;) {
        __WFI();
    }
}

int main(void)
{
    SystemClock_Config();
    CoreDebug->DEMCR |= CoreDebug_DEMCR_TRCENA_Msk; /* DWT cycle counter: ISR timing */
    DWT->CYCCNT = 0u;
    DWT->CTRL |= DWT_CTRL_CYCCNTENA_Msk;
    SCB->SHCSR |= SCB_SHCSR_BUSFAULTENA_Msk | SCB_SHCSR_USGFAULTENA_Msk | SCB_SHCSR_MEMFAULTENA_Msk;

    g.fp.rs = MOTOR_RS_OHM;
    g.fp.ld = MOTOR_LD_H;
    g.fp.lq = MOTOR_LQ_H;
    g.fp.psi_f = MOTOR_PSI_F_WB;
    g.fp.pole_pairs = MOTOR_POLE_PAIRS;
    g.fp.ts = TS_S;
    g.fp.delay_periods = 1.0f; /* sampled at the peak, applied over the next carrier period: 1 Ts to its middle */
    update_current_gains();
    foc_pll_init(&g.pll, FW_PLL_BW_RAD_S, 0.0f);

    console_init(BOARD_SYSCLK_HZ, BOARD_CONSOLE_BAUD);
    gpio_init();
    encoder_init();
    pwm_init();
    adc_init();

    NVIC_SetPriority(ADC1_2_IRQn, 0u);
    NVIC_SetPriority(SysTick_IRQn, 1u);
    NVIC_SetPriority(FDCAN1_IT0_IRQn, 2u);
    NVIC_EnableIRQ(ADC1_2_IRQn);
#if !defined(FW_NO_BUS)
    bus_ok = can_init() == 0 ? 1u : 0u;
    if (bus_ok != 0u) {
        NVIC_EnableIRQ(FDCAN1_IT0_IRQn);
    }
#endif
    console_write("stm32g4_foc: SYSCLK ");
    console_write_u32(SystemCoreClock);
    console_write(" Hz, PWM ");
    console_write_u32(BOARD_PWM_HZ);
    console_write(" Hz, dead time ");
    console_write_u32(BOARD_DEADTIME_NS);
    console_write(" ns, encoder ");
    console_write_u32(BOARD_ENCODER_LINES);
    console_write(bus_ok != 0u ? " lines, FDCAN1 up" : " lines, no bus: default setpoint");
#if defined(LATE_ISR)
    console_write(", variant LATE_ISR");
#endif
#if defined(FAULT)
    console_write(", variant FAULT");
#endif
    console_write("\r\n");
    if (bus_ok == 0u) {
        const fw_setpoint_t dflt = {1u, 0u, FW_DEFAULT_SPEED_RPM * (FOC_TWO_PI / 60.0f), CONTROLLER_EXTERNAL};
        prm.torque_init = FW_DEFAULT_TORQUE_INIT_NM;
        (void)fw_apply_setpoint(&dflt);
    }

    SysTick->LOAD = BOARD_SYSCLK_HZ / 1000u - 1u;
    SysTick->VAL = 0u;
    SysTick->CTRL = SysTick_CTRL_CLKSOURCE_Msk | SysTick_CTRL_TICKINT_Msk | SysTick_CTRL_ENABLE_Msk;
    TIM1->CR1 |= TIM_CR1_CEN; /* the carrier runs: TRGO2 at every peak starts the injected conversions */
    for (;;) {
        __WFI();
    }
}
