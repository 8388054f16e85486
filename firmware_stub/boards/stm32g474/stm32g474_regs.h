/*
 * STM32G474 register definitions, written from RM0440 (STM32G4 reference manual, rev. 8) and the Cortex-M4
 * Generic User Guide (ARM DUI 0553): only the peripherals and bits that examples/stm32g4_foc and the firmware
 * API's board layer (this folder) use.
 *
 * The names follow the CMSIS device-header convention (TIM1->CCR1, RCC_CR_HSEON, ADC_JSQR_JEXTSEL_Pos, ...), so
 * the same sources build against ST's own device header instead: configure with
 * `--define VENDOR_DEVICE_INCLUDE=DIR --define VENDOR_CMSIS_INCLUDE=DIR` (device.h, README.md).
 */
#ifndef STM32G474_REGS_H
#define STM32G474_REGS_H

#include <stdint.h>

#define __IO volatile
#define __I volatile const

/* ---- Interrupt numbers (RM0440 Table 97, "STM32G47x/G48x vector table") ---- */
typedef enum {
    NonMaskableInt_IRQn = -14,
    HardFault_IRQn = -13,
    MemoryManagement_IRQn = -12,
    BusFault_IRQn = -11,
    UsageFault_IRQn = -10,
    SVCall_IRQn = -5,
    DebugMonitor_IRQn = -4,
    PendSV_IRQn = -2,
    SysTick_IRQn = -1,
    ADC1_2_IRQn = 18,
    FDCAN1_IT0_IRQn = 21,
    FDCAN1_IT1_IRQn = 22,
    TIM1_BRK_TIM15_IRQn = 24,
    TIM1_UP_TIM16_IRQn = 25,
    TIM3_IRQn = 29,
    USART2_IRQn = 38
} IRQn_Type;

#define __NVIC_PRIO_BITS 4u /* STM32G4: 16 priority levels */

/* ---- Cortex-M4 core peripherals (ARM DUI 0553) ---- */
typedef struct {
    __IO uint32_t ISER[8];
    uint32_t RESERVED0[24];
    __IO uint32_t ICER[8];
    uint32_t RESERVED1[24];
    __IO uint32_t ISPR[8];
    uint32_t RESERVED2[24];
    __IO uint32_t ICPR[8];
    uint32_t RESERVED3[24];
    __IO uint32_t IABR[8];
    uint32_t RESERVED4[56];
    __IO uint8_t IP[240];
} NVIC_Type;

typedef struct {
    __I uint32_t CPUID;
    __IO uint32_t ICSR;
    __IO uint32_t VTOR;
    __IO uint32_t AIRCR;
    __IO uint32_t SCR;
    __IO uint32_t CCR;
    __IO uint8_t SHP[12];
    __IO uint32_t SHCSR;
    __IO uint32_t CFSR;
    __IO uint32_t HFSR;
    __IO uint32_t DFSR;
    __IO uint32_t MMFAR;
    __IO uint32_t BFAR;
    __IO uint32_t AFSR;
    uint32_t RESERVED0[18];
    __IO uint32_t CPACR;
} SCB_Type;

typedef struct {
    __IO uint32_t CTRL;
    __IO uint32_t LOAD;
    __IO uint32_t VAL;
    __I uint32_t CALIB;
} SysTick_Type;

typedef struct {
    __IO uint32_t CTRL;
    __IO uint32_t CYCCNT;
} DWT_Type;

typedef struct {
    __IO uint32_t DHCSR;
    __IO uint32_t DCRSR;
    __IO uint32_t DCRDR;
    __IO uint32_t DEMCR;
} CoreDebug_Type;

#define SCS_BASE 0xE000E000UL
#define SysTick ((SysTick_Type *)(SCS_BASE + 0x0010UL))
#define NVIC ((NVIC_Type *)(SCS_BASE + 0x0100UL))
#define SCB ((SCB_Type *)(SCS_BASE + 0x0D00UL))
#define DWT ((DWT_Type *)0xE0001000UL)
#define CoreDebug ((CoreDebug_Type *)0xE000EDF0UL)

#define SysTick_CTRL_ENABLE_Msk (1UL << 0)
#define SysTick_CTRL_TICKINT_Msk (1UL << 1)
#define SysTick_CTRL_CLKSOURCE_Msk (1UL << 2)
#define SCB_SHCSR_MEMFAULTENA_Msk (1UL << 16)
#define SCB_SHCSR_BUSFAULTENA_Msk (1UL << 17)
#define SCB_SHCSR_USGFAULTENA_Msk (1UL << 18)
#define CoreDebug_DEMCR_TRCENA_Msk (1UL << 24)
#define DWT_CTRL_CYCCNTENA_Msk (1UL << 0)

static inline void NVIC_EnableIRQ(IRQn_Type irqn)
{
    NVIC->ISER[((uint32_t)irqn) >> 5] = 1UL << (((uint32_t)irqn) & 0x1FUL);
}

static inline void NVIC_SetPriority(IRQn_Type irqn, uint32_t priority)
{
    const uint8_t v = (uint8_t)((priority << (8u - __NVIC_PRIO_BITS)) & 0xFFUL);
    if ((int32_t)irqn >= 0) {
        NVIC->IP[(uint32_t)irqn] = v;
    } else {
        SCB->SHP[(((uint32_t)irqn) & 0xFUL) - 4UL] = v;
    }
}

static inline void __enable_irq(void)
{
    __asm volatile("cpsie i" : : : "memory");
}

static inline void __disable_irq(void)
{
    __asm volatile("cpsid i" : : : "memory");
}

static inline void __DSB(void)
{
    __asm volatile("dsb 0xF" : : : "memory");
}

static inline void __ISB(void)
{
    __asm volatile("isb 0xF" : : : "memory");
}

static inline void __WFI(void)
{
    __asm volatile("wfi");
}

/* ---- Memory map (RM0440 Table 3; section 2.2.2) ---- */
#define FLASH_BASE 0x08000000UL
#define SRAM1_BASE 0x20000000UL
#define CCMSRAM_BASE 0x10000000UL
#define PERIPH_BASE 0x40000000UL
#define APB1PERIPH_BASE PERIPH_BASE
#define APB2PERIPH_BASE (PERIPH_BASE + 0x00010000UL)
#define AHB1PERIPH_BASE (PERIPH_BASE + 0x00020000UL)
#define AHB2PERIPH_BASE (PERIPH_BASE + 0x08000000UL)

#define TIM3_BASE (APB1PERIPH_BASE + 0x0400UL)
#define USART2_BASE (APB1PERIPH_BASE + 0x4400UL)
#define FDCAN1_BASE (APB1PERIPH_BASE + 0x6400UL)
#define FDCAN_CONFIG_BASE (APB1PERIPH_BASE + 0x6500UL)
#define PWR_BASE (APB1PERIPH_BASE + 0x7000UL)
#define SRAMCAN_BASE (APB1PERIPH_BASE + 0xA400UL)
#define TIM1_BASE (APB2PERIPH_BASE + 0x2C00UL)
#define RCC_BASE (AHB1PERIPH_BASE + 0x1000UL)
#define FLASH_R_BASE (AHB1PERIPH_BASE + 0x2000UL)
#define GPIOA_BASE (AHB2PERIPH_BASE + 0x0000UL)
#define GPIOB_BASE (AHB2PERIPH_BASE + 0x0400UL)
#define GPIOC_BASE (AHB2PERIPH_BASE + 0x0800UL)
#define ADC1_BASE (AHB2PERIPH_BASE + 0x08000000UL)
#define ADC2_BASE (AHB2PERIPH_BASE + 0x08000100UL)
#define ADC12_COMMON_BASE (AHB2PERIPH_BASE + 0x08000300UL)

/* ---- RCC (RM0440 section 7.4) ---- */
typedef struct {
    __IO uint32_t CR;        /* 0x00 */
    __IO uint32_t ICSCR;     /* 0x04 */
    __IO uint32_t CFGR;      /* 0x08 */
    __IO uint32_t PLLCFGR;   /* 0x0C */
    uint32_t RESERVED0[2];   /* 0x10 */
    __IO uint32_t CIER;      /* 0x18 */
    __IO uint32_t CIFR;      /* 0x1C */
    __IO uint32_t CICR;      /* 0x20 */
    uint32_t RESERVED1;      /* 0x24 */
    __IO uint32_t AHB1RSTR;  /* 0x28 */
    __IO uint32_t AHB2RSTR;  /* 0x2C */
    __IO uint32_t AHB3RSTR;  /* 0x30 */
    uint32_t RESERVED2;      /* 0x34 */
    __IO uint32_t APB1RSTR1; /* 0x38 */
    __IO uint32_t APB1RSTR2; /* 0x3C */
    __IO uint32_t APB2RSTR;  /* 0x40 */
    uint32_t RESERVED3;      /* 0x44 */
    __IO uint32_t AHB1ENR;   /* 0x48 */
    __IO uint32_t AHB2ENR;   /* 0x4C */
    __IO uint32_t AHB3ENR;   /* 0x50 */
    uint32_t RESERVED4;      /* 0x54 */
    __IO uint32_t APB1ENR1;  /* 0x58 */
    __IO uint32_t APB1ENR2;  /* 0x5C */
    __IO uint32_t APB2ENR;   /* 0x60 */
    uint32_t RESERVED5[9];   /* 0x64 .. 0x84 */
    __IO uint32_t CCIPR;     /* 0x88 */
} RCC_TypeDef;

#define RCC_CR_HSION (1UL << 8)
#define RCC_CR_HSIRDY (1UL << 10)
#define RCC_CR_HSEON (1UL << 16)
#define RCC_CR_HSERDY (1UL << 17)
#define RCC_CR_HSEBYP (1UL << 18)
#define RCC_CR_PLLON (1UL << 24)
#define RCC_CR_PLLRDY (1UL << 25)
#define RCC_CFGR_SW (3UL << 0)
#define RCC_CFGR_SW_PLL 0x00000003U
#define RCC_CFGR_SWS (3UL << 2)
#define RCC_CFGR_SWS_PLL 0x0000000CU
#define RCC_CFGR_HPRE (0xFUL << 4)
#define RCC_CFGR_HPRE_DIV1 0x00000000U
#define RCC_CFGR_HPRE_DIV2 0x00000080U
#define RCC_CFGR_PPRE1 (7UL << 8)
#define RCC_CFGR_PPRE2 (7UL << 11)
#define RCC_PLLCFGR_PLLSRC (3UL << 0)
#define RCC_PLLCFGR_PLLSRC_HSI (2UL << 0)
#define RCC_PLLCFGR_PLLSRC_HSE (3UL << 0)
#define RCC_PLLCFGR_PLLM_Pos 4U
#define RCC_PLLCFGR_PLLM (0xFUL << 4)
#define RCC_PLLCFGR_PLLN_Pos 8U
#define RCC_PLLCFGR_PLLN (0x7FUL << 8)
#define RCC_PLLCFGR_PLLREN (1UL << 24)
#define RCC_PLLCFGR_PLLR_Pos 25U
#define RCC_PLLCFGR_PLLR (3UL << 25)
#define RCC_AHB2ENR_GPIOAEN (1UL << 0)
#define RCC_AHB2ENR_GPIOBEN (1UL << 1)
#define RCC_AHB2ENR_GPIOCEN (1UL << 2)
#define RCC_AHB2ENR_ADC12EN (1UL << 13)
#define RCC_APB1ENR1_TIM3EN (1UL << 1)
#define RCC_APB1ENR1_USART2EN (1UL << 17)
#define RCC_APB1ENR1_FDCANEN (1UL << 25)
#define RCC_APB1ENR1_PWREN (1UL << 28)
#define RCC_APB2ENR_SYSCFGEN (1UL << 0)
#define RCC_APB2ENR_TIM1EN (1UL << 11)
#define RCC_CCIPR_USART2SEL_Pos 2U
#define RCC_CCIPR_USART2SEL (3UL << 2)
#define RCC_CCIPR_FDCANSEL_Pos 24U
#define RCC_CCIPR_FDCANSEL (3UL << 24)
#define RCC_CCIPR_ADC12SEL_Pos 28U
#define RCC_CCIPR_ADC12SEL (3UL << 28)

/* ---- PWR (RM0440 section 6.4) ---- */
typedef struct {
    __IO uint32_t CR1;       /* 0x00 */
    __IO uint32_t CR2;       /* 0x04 */
    __IO uint32_t CR3;       /* 0x08 */
    __IO uint32_t CR4;       /* 0x0C */
    __IO uint32_t SR1;       /* 0x10 */
    __IO uint32_t SR2;       /* 0x14 */
    __IO uint32_t SCR;       /* 0x18 */
    uint32_t RESERVED0[25];  /* 0x1C .. 0x7C */
    __IO uint32_t CR5;       /* 0x80 */
} PWR_TypeDef;

#define PWR_CR1_VOS_Pos 9U
#define PWR_CR1_VOS (3UL << 9)
#define PWR_CR1_VOS_0 (1UL << 9) /* range 1 */
#define PWR_SR2_VOSF (1UL << 10)
#define PWR_CR5_R1MODE (1UL << 8) /* 0: range 1 boost mode (SYSCLK up to 170 MHz) */

/* ---- FLASH interface (RM0440 section 5.7) ---- */
typedef struct {
    __IO uint32_t ACR;     /* 0x00 */
    __IO uint32_t PDKEYR;  /* 0x04 */
    __IO uint32_t KEYR;    /* 0x08 */
    __IO uint32_t OPTKEYR; /* 0x0C */
    __IO uint32_t SR;      /* 0x10 */
    __IO uint32_t CR;      /* 0x14 */
} FLASH_TypeDef;

#define FLASH_ACR_LATENCY (0xFUL << 0)
#define FLASH_ACR_LATENCY_4WS 0x00000004U
#define FLASH_ACR_PRFTEN (1UL << 8)
#define FLASH_ACR_ICEN (1UL << 9)
#define FLASH_ACR_DCEN (1UL << 10)

/* ---- GPIO (RM0440 section 9.4) ---- */
typedef struct {
    __IO uint32_t MODER;   /* 0x00 */
    __IO uint32_t OTYPER;  /* 0x04 */
    __IO uint32_t OSPEEDR; /* 0x08 */
    __IO uint32_t PUPDR;   /* 0x0C */
    __IO uint32_t IDR;     /* 0x10 */
    __IO uint32_t ODR;     /* 0x14 */
    __IO uint32_t BSRR;    /* 0x18 */
    __IO uint32_t LCKR;    /* 0x1C */
    __IO uint32_t AFR[2];  /* 0x20, 0x24 */
    __IO uint32_t BRR;     /* 0x28 */
} GPIO_TypeDef;

/* ---- Advanced-control and general-purpose timers (RM0440 sections 28.6, 29.5) ---- */
typedef struct {
    __IO uint32_t CR1;   /* 0x00 */
    __IO uint32_t CR2;   /* 0x04 */
    __IO uint32_t SMCR;  /* 0x08 */
    __IO uint32_t DIER;  /* 0x0C */
    __IO uint32_t SR;    /* 0x10 */
    __IO uint32_t EGR;   /* 0x14 */
    __IO uint32_t CCMR1; /* 0x18 */
    __IO uint32_t CCMR2; /* 0x1C */
    __IO uint32_t CCER;  /* 0x20 */
    __IO uint32_t CNT;   /* 0x24 */
    __IO uint32_t PSC;   /* 0x28 */
    __IO uint32_t ARR;   /* 0x2C */
    __IO uint32_t RCR;   /* 0x30 */
    __IO uint32_t CCR1;  /* 0x34 */
    __IO uint32_t CCR2;  /* 0x38 */
    __IO uint32_t CCR3;  /* 0x3C */
    __IO uint32_t CCR4;  /* 0x40 */
    __IO uint32_t BDTR;  /* 0x44 */
    __IO uint32_t CCR5;  /* 0x48 */
    __IO uint32_t CCR6;  /* 0x4C */
    __IO uint32_t CCMR3; /* 0x50 */
    __IO uint32_t DTR2;  /* 0x54 */
    __IO uint32_t ECR;   /* 0x58 */
    __IO uint32_t TISEL; /* 0x5C */
    __IO uint32_t AF1;   /* 0x60 */
    __IO uint32_t AF2;   /* 0x64 */
} TIM_TypeDef;

#define TIM_CR1_CEN (1UL << 0)
#define TIM_CR1_URS (1UL << 2)
#define TIM_CR1_DIR (1UL << 4)
#define TIM_CR1_CMS_Pos 5U
#define TIM_CR1_CMS_0 (1UL << 5) /* centre-aligned mode 1 */
#define TIM_CR1_ARPE (1UL << 7)
#define TIM_CR2_MMS_Pos 4U
#define TIM_CR2_MMS2_Pos 20U
#define TIM_CR2_MMS2 (0xFUL << 20)
#define TIM_SMCR_SMS_Pos 0U
#define TIM_SMCR_SMS (0x10007UL << 0)
#define TIM_DIER_UIE (1UL << 0)
#define TIM_SR_UIF (1UL << 0)
#define TIM_EGR_UG (1UL << 0)
#define TIM_CCMR1_CC1S_0 (1UL << 0)
#define TIM_CCMR1_OC1PE (1UL << 3)
#define TIM_CCMR1_OC1M_Pos 4U
#define TIM_CCMR1_IC1F_Pos 4U
#define TIM_CCMR1_CC2S_0 (1UL << 8)
#define TIM_CCMR1_OC2PE (1UL << 11)
#define TIM_CCMR1_OC2M_Pos 12U
#define TIM_CCMR1_IC2F_Pos 12U
#define TIM_CCMR2_OC3PE (1UL << 3)
#define TIM_CCMR2_OC3M_Pos 4U
#define TIM_CCMR2_OC4PE (1UL << 11)
#define TIM_CCMR2_OC4M_Pos 12U
#define TIM_CCER_CC1E (1UL << 0)
#define TIM_CCER_CC1NE (1UL << 2)
#define TIM_CCER_CC2E (1UL << 4)
#define TIM_CCER_CC2NE (1UL << 6)
#define TIM_CCER_CC3E (1UL << 8)
#define TIM_CCER_CC3NE (1UL << 10)
#define TIM_CCER_CC4E (1UL << 12)
#define TIM_BDTR_DTG_Pos 0U
#define TIM_BDTR_DTG (0xFFUL << 0)
#define TIM_BDTR_OSSI (1UL << 10)
#define TIM_BDTR_OSSR (1UL << 11)
#define TIM_BDTR_MOE (1UL << 15)

/* ---- ADC (RM0440 section 21.7) ---- */
typedef struct {
    __IO uint32_t ISR;        /* 0x00 */
    __IO uint32_t IER;        /* 0x04 */
    __IO uint32_t CR;         /* 0x08 */
    __IO uint32_t CFGR;       /* 0x0C */
    __IO uint32_t CFGR2;      /* 0x10 */
    __IO uint32_t SMPR1;      /* 0x14 */
    __IO uint32_t SMPR2;      /* 0x18 */
    uint32_t RESERVED1;       /* 0x1C */
    __IO uint32_t TR1;        /* 0x20 */
    __IO uint32_t TR2;        /* 0x24 */
    __IO uint32_t TR3;        /* 0x28 */
    uint32_t RESERVED2;       /* 0x2C */
    __IO uint32_t SQR1;       /* 0x30 */
    __IO uint32_t SQR2;       /* 0x34 */
    __IO uint32_t SQR3;       /* 0x38 */
    __IO uint32_t SQR4;       /* 0x3C */
    __IO uint32_t DR;         /* 0x40 */
    uint32_t RESERVED3[2];    /* 0x44, 0x48 */
    __IO uint32_t JSQR;       /* 0x4C */
    uint32_t RESERVED4[4];    /* 0x50 .. 0x5C */
    __IO uint32_t OFR1;       /* 0x60 */
    __IO uint32_t OFR2;       /* 0x64 */
    __IO uint32_t OFR3;       /* 0x68 */
    __IO uint32_t OFR4;       /* 0x6C */
    uint32_t RESERVED5[4];    /* 0x70 .. 0x7C */
    __IO uint32_t JDR1;       /* 0x80 */
    __IO uint32_t JDR2;       /* 0x84 */
    __IO uint32_t JDR3;       /* 0x88 */
    __IO uint32_t JDR4;       /* 0x8C */
} ADC_TypeDef;

typedef struct {
    __IO uint32_t CSR;     /* 0x300 */
    uint32_t RESERVED1;    /* 0x304 */
    __IO uint32_t CCR;     /* 0x308 */
    __IO uint32_t CDR;     /* 0x30C */
} ADC_Common_TypeDef;

#define ADC_ISR_ADRDY (1UL << 0)
#define ADC_ISR_JEOC (1UL << 5)
#define ADC_ISR_JEOS (1UL << 6)
#define ADC_IER_JEOSIE (1UL << 6)
#define ADC_CR_ADEN (1UL << 0)
#define ADC_CR_ADDIS (1UL << 1)
#define ADC_CR_JADSTART (1UL << 3)
#define ADC_CR_ADVREGEN (1UL << 28)
#define ADC_CR_DEEPPWD (1UL << 29)
#define ADC_CR_ADCALDIF (1UL << 30)
#define ADC_CR_ADCAL (1UL << 31)
#define ADC_CFGR_JQDIS (1UL << 31)
#define ADC_SMPR1_SMP1_Pos 3U
#define ADC_SMPR1_SMP2_Pos 6U
#define ADC_SMPR2_SMP12_Pos 6U
#define ADC_JSQR_JL_Pos 0U
#define ADC_JSQR_JEXTSEL_Pos 2U
#define ADC_JSQR_JEXTEN_Pos 7U
#define ADC_JSQR_JSQ1_Pos 9U
#define ADC_JSQR_JSQ2_Pos 15U
#define ADC_CCR_CKMODE_Pos 16U
#define ADC_CCR_CKMODE (3UL << 16)

/* ---- USART (RM0440 section 37.8) ---- */
typedef struct {
    __IO uint32_t CR1;   /* 0x00 */
    __IO uint32_t CR2;   /* 0x04 */
    __IO uint32_t CR3;   /* 0x08 */
    __IO uint32_t BRR;   /* 0x0C */
    __IO uint32_t GTPR;  /* 0x10 */
    __IO uint32_t RTOR;  /* 0x14 */
    __IO uint32_t RQR;   /* 0x18 */
    __IO uint32_t ISR;   /* 0x1C */
    __IO uint32_t ICR;   /* 0x20 */
    __IO uint32_t RDR;   /* 0x24 */
    __IO uint32_t TDR;   /* 0x28 */
    __IO uint32_t PRESC; /* 0x2C */
} USART_TypeDef;

#define USART_CR1_UE (1UL << 0)
#define USART_CR1_RE (1UL << 2)
#define USART_CR1_TE (1UL << 3)
#define USART_ISR_TC (1UL << 6)
#define USART_ISR_TXE_TXFNF (1UL << 7)

/* ---- FDCAN (RM0440 section 44.4) ---- */
typedef struct {
    __IO uint32_t CREL;       /* 0x000 */
    __IO uint32_t ENDN;       /* 0x004 */
    uint32_t RESERVED1;       /* 0x008 */
    __IO uint32_t DBTP;       /* 0x00C */
    __IO uint32_t TEST;       /* 0x010 */
    __IO uint32_t RWD;        /* 0x014 */
    __IO uint32_t CCCR;       /* 0x018 */
    __IO uint32_t NBTP;       /* 0x01C */
    __IO uint32_t TSCC;       /* 0x020 */
    __IO uint32_t TSCV;       /* 0x024 */
    __IO uint32_t TOCC;       /* 0x028 */
    __IO uint32_t TOCV;       /* 0x02C */
    uint32_t RESERVED2[4];    /* 0x030 .. 0x03C */
    __IO uint32_t ECR;        /* 0x040 */
    __IO uint32_t PSR;        /* 0x044 */
    __IO uint32_t TDCR;       /* 0x048 */
    uint32_t RESERVED3;       /* 0x04C */
    __IO uint32_t IR;         /* 0x050 */
    __IO uint32_t IE;         /* 0x054 */
    __IO uint32_t ILS;        /* 0x058 */
    __IO uint32_t ILE;        /* 0x05C */
    uint32_t RESERVED4[8];    /* 0x060 .. 0x07C */
    __IO uint32_t RXGFC;      /* 0x080 */
    __IO uint32_t XIDAM;      /* 0x084 */
    __IO uint32_t HPMS;       /* 0x088 */
    uint32_t RESERVED5;       /* 0x08C */
    __IO uint32_t RXF0S;      /* 0x090 */
    __IO uint32_t RXF0A;      /* 0x094 */
    __IO uint32_t RXF1S;      /* 0x098 */
    __IO uint32_t RXF1A;      /* 0x09C */
    uint32_t RESERVED6[8];    /* 0x0A0 .. 0x0BC */
    __IO uint32_t TXBC;       /* 0x0C0 */
    __IO uint32_t TXFQS;      /* 0x0C4 */
    __IO uint32_t TXBRP;      /* 0x0C8 */
    __IO uint32_t TXBAR;      /* 0x0CC */
} FDCAN_GlobalTypeDef;

#define FDCAN_CCCR_INIT (1UL << 0)
#define FDCAN_CCCR_CCE (1UL << 1)
#define FDCAN_CCCR_FDOE (1UL << 8)
#define FDCAN_CCCR_BRSE (1UL << 9)
#define FDCAN_NBTP_NTSEG2_Pos 0U
#define FDCAN_NBTP_NTSEG1_Pos 8U
#define FDCAN_NBTP_NBRP_Pos 16U
#define FDCAN_NBTP_NSJW_Pos 25U
#define FDCAN_DBTP_DSJW_Pos 0U
#define FDCAN_DBTP_DTSEG2_Pos 4U
#define FDCAN_DBTP_DTSEG1_Pos 8U
#define FDCAN_DBTP_DBRP_Pos 16U
#define FDCAN_IR_RF0N (1UL << 0)
#define FDCAN_IR_RF0L (1UL << 3)
#define FDCAN_IE_RF0NE (1UL << 0)
#define FDCAN_ILS_RXFIFO0 (1UL << 0)
#define FDCAN_ILE_EINT0 (1UL << 0)
#define FDCAN_RXGFC_ANFS_Pos 4U
#define FDCAN_RXGFC_ANFE_Pos 2U
#define FDCAN_RXGFC_RRFS (1UL << 1)
#define FDCAN_RXGFC_RRFE (1UL << 0)
#define FDCAN_RXGFC_LSS_Pos 16U
#define FDCAN_RXF0S_F0FL (0xFUL << 0)
#define FDCAN_RXF0S_F0GI_Pos 8U
#define FDCAN_RXF0S_F0GI (3UL << 8)
#define FDCAN_RXF0S_RF0L (1UL << 25)
#define FDCAN_TXFQS_TFQPI_Pos 16U
#define FDCAN_TXFQS_TFQPI (3UL << 16)
#define FDCAN_TXFQS_TFQF (1UL << 21)
#define FDCAN_TXBC_TFQM (1UL << 24)
#define FDCAN_DBTP_TDC (1UL << 23)
#define FDCAN_TDCR_TDCO_Pos 8U
#define FDCAN_CCCR_TEST (1UL << 7)
#define FDCAN_TEST_LBCK (1UL << 4)

/* ---- Instances ---- */
#define RCC ((RCC_TypeDef *)RCC_BASE)
#define PWR ((PWR_TypeDef *)PWR_BASE)
#define FLASH ((FLASH_TypeDef *)FLASH_R_BASE)
#define GPIOA ((GPIO_TypeDef *)GPIOA_BASE)
#define GPIOB ((GPIO_TypeDef *)GPIOB_BASE)
#define GPIOC ((GPIO_TypeDef *)GPIOC_BASE)
#define TIM1 ((TIM_TypeDef *)TIM1_BASE)
#define TIM3 ((TIM_TypeDef *)TIM3_BASE)
#define ADC1 ((ADC_TypeDef *)ADC1_BASE)
#define ADC2 ((ADC_TypeDef *)ADC2_BASE)
#define ADC12_COMMON ((ADC_Common_TypeDef *)ADC12_COMMON_BASE)
#define USART2 ((USART_TypeDef *)USART2_BASE)
#define FDCAN1 ((FDCAN_GlobalTypeDef *)FDCAN1_BASE)

/* ---- CMSIS system interface (what ST's system_stm32g4xx.h declares) ---- */
extern uint32_t SystemCoreClock; /* the core clock [Hz] */
void SystemInit(void);

#endif /* STM32G474_REGS_H */
