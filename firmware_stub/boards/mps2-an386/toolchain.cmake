# arm-none-eabi-gcc/g++ for the Cortex-M4F of QEMU's mps2-an386 (the flags: ../cortex-m4f.cmake).
include("${CMAKE_CURRENT_LIST_DIR}/../cortex-m4f.cmake")
set(HIL_BOARD mps2-an386 CACHE STRING "HIL board")
