# arm-none-eabi-gcc for an STM32G474 (Cortex-M4F, hard-float ABI, single-precision FPU): a bare-metal firmware
# that owns its start-up, vector table and linker script (hil_add_board_firmware() of hil_target.cmake), run by
# `hil run --target stm32g4:PATH.elf` on the virtual board.
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(HIL_MCU_FLAGS "-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard")
set(CMAKE_C_FLAGS_INIT "${HIL_MCU_FLAGS} -ffunction-sections -fdata-sections")
set(CMAKE_CXX_FLAGS_INIT "${HIL_MCU_FLAGS} -ffunction-sections -fdata-sections")
set(CMAKE_EXE_LINKER_FLAGS_INIT "${HIL_MCU_FLAGS}")
set(HIL_BOARD stm32g474 CACHE STRING "HIL board")
