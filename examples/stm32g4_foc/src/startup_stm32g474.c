/*
 * Start-up of the STM32G474 (Cortex-M4F): the vector table at 0x08000000 with the 16 system exceptions and the
 * 102 interrupt lines of RM0440 Table 97 (position = IRQ number), the reset handler (FPU on via CPACR, .data
 * copied from flash, .bss and the CCM-SRAM .ccmbss zeroed, .ccmdata copied, SystemInit, main) and the fault
 * handlers. Every handler the firmware does not define is a weak alias of Default_Handler.
 */
#include <stdint.h>

#include "device.h"
#include "fw.h"
#include "stm32g474_ll.h"

extern uint32_t _estack;

int main(void);
void SystemInit(void);
void Reset_Handler(void);
void Default_Handler(void);
void NMI_Handler(void) __attribute__((weak, alias("Default_Handler")));
void HardFault_Handler(void);
void MemManage_Handler(void);
void BusFault_Handler(void);
void UsageFault_Handler(void);
void SVC_Handler(void) __attribute__((weak, alias("Default_Handler")));
void DebugMon_Handler(void) __attribute__((weak, alias("Default_Handler")));
void PendSV_Handler(void) __attribute__((weak, alias("Default_Handler")));
void SysTick_Handler(void) __attribute__((weak, alias("Default_Handler")));
void WWDG_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void PVD_PVM_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void RTC_TAMP_LSECSS_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void RTC_WKUP_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void FLASH_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void RCC_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI0_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI3_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI4_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA1_Channel1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA1_Channel2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA1_Channel3_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA1_Channel4_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA1_Channel5_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA1_Channel6_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA1_Channel7_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void ADC1_2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void USB_HP_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void USB_LP_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void FDCAN1_IT0_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void FDCAN1_IT1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI9_5_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM1_BRK_TIM15_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM1_UP_TIM16_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM1_TRG_COM_TIM17_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM1_CC_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM3_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM4_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void I2C1_EV_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void I2C1_ER_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void I2C2_EV_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void I2C2_ER_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void SPI1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void SPI2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void USART1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void USART2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void USART3_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void EXTI15_10_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void RTC_Alarm_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void USBWakeUp_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM8_BRK_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM8_UP_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM8_TRG_COM_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM8_CC_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void ADC3_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void FMC_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void LPTIM1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM5_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void SPI3_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void UART4_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void UART5_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM6_DAC_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM7_DAC_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA2_Channel1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA2_Channel2_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA2_Channel3_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA2_Channel4_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA2_Channel5_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void ADC4_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void ADC5_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void UCPD1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void COMP1_2_3_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void COMP4_5_6_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void COMP7_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void HRTIM1_Master_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void HRTIM1_TIMA_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void HRTIM1_TIMB_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void HRTIM1_TIMC_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void HRTIM1_TIMD_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void HRTIM1_TIME_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void HRTIM1_FLT_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void HRTIM1_TIMF_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void CRS_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void SAI1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM20_BRK_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM20_UP_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM20_TRG_COM_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void TIM20_CC_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void FPU_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void I2C4_EV_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void I2C4_ER_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void SPI4_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void FDCAN2_IT0_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void FDCAN2_IT1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void FDCAN3_IT0_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void FDCAN3_IT1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void RNG_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void LPUART1_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void I2C3_EV_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void I2C3_ER_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMAMUX_OVR_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void QUADSPI_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA1_Channel8_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA2_Channel6_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA2_Channel7_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void DMA2_Channel8_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void CORDIC_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));
void FMAC_IRQHandler(void) __attribute__((weak, alias("Default_Handler")));

typedef void (*vector_t)(void);

__attribute__((section(".isr_vector"), used)) const vector_t g_pfnVectors[16 + 102] = {
    (vector_t)(uintptr_t)&_estack,
    Reset_Handler,
    NMI_Handler,
    HardFault_Handler,
    MemManage_Handler,
    BusFault_Handler,
    UsageFault_Handler,
    0,
    0,
    0,
    0,
    SVC_Handler,
    DebugMon_Handler,
    0,
    PendSV_Handler,
    SysTick_Handler,
    WWDG_IRQHandler, /* IRQ 0 */
    PVD_PVM_IRQHandler, /* IRQ 1 */
    RTC_TAMP_LSECSS_IRQHandler, /* IRQ 2 */
    RTC_WKUP_IRQHandler, /* IRQ 3 */
    FLASH_IRQHandler, /* IRQ 4 */
    RCC_IRQHandler, /* IRQ 5 */
    EXTI0_IRQHandler, /* IRQ 6 */
    EXTI1_IRQHandler, /* IRQ 7 */
    EXTI2_IRQHandler, /* IRQ 8 */
    EXTI3_IRQHandler, /* IRQ 9 */
    EXTI4_IRQHandler, /* IRQ 10 */
    DMA1_Channel1_IRQHandler, /* IRQ 11 */
    DMA1_Channel2_IRQHandler, /* IRQ 12 */
    DMA1_Channel3_IRQHandler, /* IRQ 13 */
    DMA1_Channel4_IRQHandler, /* IRQ 14 */
    DMA1_Channel5_IRQHandler, /* IRQ 15 */
    DMA1_Channel6_IRQHandler, /* IRQ 16 */
    DMA1_Channel7_IRQHandler, /* IRQ 17 */
    ADC1_2_IRQHandler, /* IRQ 18 */
    USB_HP_IRQHandler, /* IRQ 19 */
    USB_LP_IRQHandler, /* IRQ 20 */
    FDCAN1_IT0_IRQHandler, /* IRQ 21 */
    FDCAN1_IT1_IRQHandler, /* IRQ 22 */
    EXTI9_5_IRQHandler, /* IRQ 23 */
    TIM1_BRK_TIM15_IRQHandler, /* IRQ 24 */
    TIM1_UP_TIM16_IRQHandler, /* IRQ 25 */
    TIM1_TRG_COM_TIM17_IRQHandler, /* IRQ 26 */
    TIM1_CC_IRQHandler, /* IRQ 27 */
    TIM2_IRQHandler, /* IRQ 28 */
    TIM3_IRQHandler, /* IRQ 29 */
    TIM4_IRQHandler, /* IRQ 30 */
    I2C1_EV_IRQHandler, /* IRQ 31 */
    I2C1_ER_IRQHandler, /* IRQ 32 */
    I2C2_EV_IRQHandler, /* IRQ 33 */
    I2C2_ER_IRQHandler, /* IRQ 34 */
    SPI1_IRQHandler, /* IRQ 35 */
    SPI2_IRQHandler, /* IRQ 36 */
    USART1_IRQHandler, /* IRQ 37 */
    USART2_IRQHandler, /* IRQ 38 */
    USART3_IRQHandler, /* IRQ 39 */
    EXTI15_10_IRQHandler, /* IRQ 40 */
    RTC_Alarm_IRQHandler, /* IRQ 41 */
    USBWakeUp_IRQHandler, /* IRQ 42 */
    TIM8_BRK_IRQHandler, /* IRQ 43 */
    TIM8_UP_IRQHandler, /* IRQ 44 */
    TIM8_TRG_COM_IRQHandler, /* IRQ 45 */
    TIM8_CC_IRQHandler, /* IRQ 46 */
    ADC3_IRQHandler, /* IRQ 47 */
    FMC_IRQHandler, /* IRQ 48 */
    LPTIM1_IRQHandler, /* IRQ 49 */
    TIM5_IRQHandler, /* IRQ 50 */
    SPI3_IRQHandler, /* IRQ 51 */
    UART4_IRQHandler, /* IRQ 52 */
    UART5_IRQHandler, /* IRQ 53 */
    TIM6_DAC_IRQHandler, /* IRQ 54 */
    TIM7_DAC_IRQHandler, /* IRQ 55 */
    DMA2_Channel1_IRQHandler, /* IRQ 56 */
    DMA2_Channel2_IRQHandler, /* IRQ 57 */
    DMA2_Channel3_IRQHandler, /* IRQ 58 */
    DMA2_Channel4_IRQHandler, /* IRQ 59 */
    DMA2_Channel5_IRQHandler, /* IRQ 60 */
    ADC4_IRQHandler, /* IRQ 61 */
    ADC5_IRQHandler, /* IRQ 62 */
    UCPD1_IRQHandler, /* IRQ 63 */
    COMP1_2_3_IRQHandler, /* IRQ 64 */
    COMP4_5_6_IRQHandler, /* IRQ 65 */
    COMP7_IRQHandler, /* IRQ 66 */
    HRTIM1_Master_IRQHandler, /* IRQ 67 */
    HRTIM1_TIMA_IRQHandler, /* IRQ 68 */
    HRTIM1_TIMB_IRQHandler, /* IRQ 69 */
    HRTIM1_TIMC_IRQHandler, /* IRQ 70 */
    HRTIM1_TIMD_IRQHandler, /* IRQ 71 */
    HRTIM1_TIME_IRQHandler, /* IRQ 72 */
    HRTIM1_FLT_IRQHandler, /* IRQ 73 */
    HRTIM1_TIMF_IRQHandler, /* IRQ 74 */
    CRS_IRQHandler, /* IRQ 75 */
    SAI1_IRQHandler, /* IRQ 76 */
    TIM20_BRK_IRQHandler, /* IRQ 77 */
    TIM20_UP_IRQHandler, /* IRQ 78 */
    TIM20_TRG_COM_IRQHandler, /* IRQ 79 */
    TIM20_CC_IRQHandler, /* IRQ 80 */
    FPU_IRQHandler, /* IRQ 81 */
    I2C4_EV_IRQHandler, /* IRQ 82 */
    I2C4_ER_IRQHandler, /* IRQ 83 */
    SPI4_IRQHandler, /* IRQ 84 */
    0, /* IRQ 85 */
    FDCAN2_IT0_IRQHandler, /* IRQ 86 */
    FDCAN2_IT1_IRQHandler, /* IRQ 87 */
    FDCAN3_IT0_IRQHandler, /* IRQ 88 */
    FDCAN3_IT1_IRQHandler, /* IRQ 89 */
    RNG_IRQHandler, /* IRQ 90 */
    LPUART1_IRQHandler, /* IRQ 91 */
    I2C3_EV_IRQHandler, /* IRQ 92 */
    I2C3_ER_IRQHandler, /* IRQ 93 */
    DMAMUX_OVR_IRQHandler, /* IRQ 94 */
    QUADSPI_IRQHandler, /* IRQ 95 */
    DMA1_Channel8_IRQHandler, /* IRQ 96 */
    DMA2_Channel6_IRQHandler, /* IRQ 97 */
    DMA2_Channel7_IRQHandler, /* IRQ 98 */
    DMA2_Channel8_IRQHandler, /* IRQ 99 */
    CORDIC_IRQHandler, /* IRQ 100 */
    FMAC_IRQHandler, /* IRQ 101 */
};

void Reset_Handler(void)
{
    g4_reset_init(); /* the FPU on, .data and .ccmdata copied, .bss and .ccmbss zeroed */
    SystemInit();
    (void)main();
    for (;;) {
        __WFI();
    }
}

void Default_Handler(void)
{
    fw_fault_stop(0u);
}

/* Faults: record the fault status (CFSR) and stop the drive (MOE off, gates disabled); the debugger or the
 * virtual board's fault report reads the stacked pc/lr. */
void HardFault_Handler(void)
{
    fw_fault_stop(3u);
}

void MemManage_Handler(void)
{
    fw_fault_stop(4u);
}

void BusFault_Handler(void)
{
    fw_fault_stop(5u);
}

void UsageFault_Handler(void)
{
    fw_fault_stop(6u);
}
