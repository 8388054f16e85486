/*
 * The device header the firmware includes: the project's own RM0440 definitions (stm32g474_regs.h), or ST's
 * CMSIS device header when the build names one (USE_VENDOR_DEVICE_HEADER, set by CMakeLists.txt when configured
 * with VENDOR_DEVICE_INCLUDE and VENDOR_CMSIS_INCLUDE: the folders holding stm32g474xx.h and core_cm4.h).
 */
#ifndef FW_DEVICE_H
#define FW_DEVICE_H

#if defined(USE_VENDOR_DEVICE_HEADER)
#include "stm32g474xx.h"
#else
#include "stm32g474_regs.h"
#endif

#endif /* FW_DEVICE_H */
