# arm-none-eabi-gcc/g++ for a Cortex-M4F (hard-float ABI, single-precision FPU), included by the boards'
# toolchain files. C and C++ get the same ABI flags (a C++ object built without them does not link: "uses VFP
# register arguments"); hil_target.cmake adds the per-language flags (-std=c99 on C only; -fno-exceptions -fno-rtti
# on C++) and -ffp-contract=off (HIL_FP_CONTRACT, docs/firmware_api.md "SIL and QEMU bit-identical").
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(HIL_MCU_FLAGS "-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard")
set(CMAKE_C_FLAGS_INIT "${HIL_MCU_FLAGS} -ffunction-sections -fdata-sections")
set(CMAKE_CXX_FLAGS_INIT "${HIL_MCU_FLAGS} -ffunction-sections -fdata-sections")
set(CMAKE_EXE_LINKER_FLAGS_INIT "${HIL_MCU_FLAGS}")
