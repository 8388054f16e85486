# arm-none-eabi-gcc for an STM32G474 (Cortex-M4F, hard-float ABI, single-precision FPU: ../cortex-m4f.cmake): a
# bare-metal firmware that owns its start-up, vector table and linker script (hil_add_board_firmware() of
# hil_target.cmake), run by `hil run --target stm32g4:PATH.elf` on the virtual board.
include("${CMAKE_CURRENT_LIST_DIR}/../cortex-m4f.cmake")
set(HIL_BOARD stm32g474 CACHE STRING "HIL board")
