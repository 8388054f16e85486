# Build a firmware behind the HIL target core (docs/firmware_api.md).
#
#   include(${HIL_SDK}/target/hil_target.cmake)      # `hil fw build` passes -DHIL_SDK and -DHIL_BOARD
#   hil_add_firmware(my_fw SOURCES my_control.c [INCLUDES dir...] [STRICT])
#
# HIL_BOARD host: a shared library out/libhil_firmware.so for `hil run --target sil:PATH`;
# HIL_BOARD mps2-an386: a Cortex-M4F ELF out/hil_firmware.elf for `hil run --target qemu:PATH` (configure
# with -DCMAKE_TOOLCHAIN_FILE=${HIL_SDK}/boards/mps2-an386/toolchain.cmake); HIL_BOARD stm32g474: below. The core, the generated codec
# and the board layer are compiled with the project's strict flags; STRICT applies them to SOURCES too.
#
# Languages: C sources get -std=c99, C++ sources (.cpp/.cc/.cxx; enable CXX in project()) -std=c++17
# -fno-exceptions -fno-rtti; both boards build the same sources with the same language flags. The MCU start-up
# runs the C++ static constructors (__libc_init_array) before main.
# HIL_FP_CONTRACT (default off): -ffp-contract=off on every source, so the M4F does not fuse a*b+c into one
# VFMA (x86-64 does not either) and SIL and QEMU runs of one firmware are bit-identical; `--define
# HIL_FP_CONTRACT=fast` lets the compiler fuse again (a few % fewer instructions, SIL no longer an exact oracle).
# `hil fw build --define NAME=VALUE` sets NAME both as a CMake variable and as a preprocessor macro of the
# firmware (HIL_DEFINES). The host library links with --no-undefined: a missing hil_app_* is a build error.
#
# HIL_BOARD stm32g474 (toolchain ${HIL_SDK}/boards/stm32g474/toolchain.cmake): hil_add_firmware() builds the
# target core on the STM32G474 board layer (boards/stm32g474/: start-up, 170 MHz clocks, FDCAN1 carrying the
# frames, DWT as the execution clock) into out/hil_firmware.elf, the image for a real NUCLEO-G474RE on a CAN FD
# bench and for `hil run --target stm32g4:PATH` (the virtual board, over its emulated FDCAN1). A bare-metal
# firmware that owns its start-up, vector table and linker script and talks to the plant through the chip's
# peripherals, not through the target core, uses instead:
#   hil_add_board_firmware(my_fw SOURCES ... LINKER_SCRIPT file.ld [INCLUDES dir...] [CODEC])
# builds out/hil_firmware.elf (and its .map) with the strict flags; CODEC adds the generated DBC codec
# (generated/hil_protocol.c, its header on the include path).
get_filename_component(HIL_SDK "${CMAKE_CURRENT_LIST_DIR}/.." ABSOLUTE)
if(NOT HIL_BOARD)
    set(HIL_BOARD host)
endif()
if(NOT HIL_FP_CONTRACT)
    set(HIL_FP_CONTRACT off)
endif()
set(HIL_C_ONLY $<$<COMPILE_LANGUAGE:C>:-std=c99>)
set(HIL_CXX_ONLY $<$<COMPILE_LANGUAGE:CXX>:-std=c++17> $<$<COMPILE_LANGUAGE:CXX>:-fno-exceptions>
    $<$<COMPILE_LANGUAGE:CXX>:-fno-rtti>)
set(HIL_STRICT_FLAGS ${HIL_C_ONLY} ${HIL_CXX_ONLY} -Wall -Wextra -Werror -Wdouble-promotion
    -fsingle-precision-constant -O2 -ffp-contract=${HIL_FP_CONTRACT})
set(HIL_USER_FLAGS ${HIL_C_ONLY} ${HIL_CXX_ONLY} -Wall -Wextra -O2 -ffp-contract=${HIL_FP_CONTRACT})

function(hil_add_firmware name)
    cmake_parse_arguments(FW "STRICT" "" "SOURCES;INCLUDES" ${ARGN})
    set(core "${HIL_SDK}/target/hil_target_core.c" "${HIL_SDK}/generated/hil_protocol.c")
    if(HIL_BOARD STREQUAL "host")
        list(APPEND core "${HIL_SDK}/boards/host/hil_sil.c")
        add_library(${name} SHARED ${FW_SOURCES} ${core})
        set_target_properties(${name} PROPERTIES OUTPUT_NAME hil_firmware PREFIX "lib" SUFFIX ".so"
                              LIBRARY_OUTPUT_DIRECTORY "${CMAKE_BINARY_DIR}/out")
        target_link_libraries(${name} PRIVATE m)
        target_link_options(${name} PRIVATE -Wl,--no-undefined)
    elseif(HIL_BOARD STREQUAL "mps2-an386")
        set(board "${HIL_SDK}/boards/mps2-an386")
        list(APPEND core "${HIL_SDK}/target/hil_serial.c" "${board}/startup.c" "${board}/board.c")
        add_executable(${name} ${FW_SOURCES} ${core})
        set_target_properties(${name} PROPERTIES OUTPUT_NAME hil_firmware SUFFIX ".elf"
                              RUNTIME_OUTPUT_DIRECTORY "${CMAKE_BINARY_DIR}/out")
        target_link_options(${name} PRIVATE "-T${board}/mps2-an386.ld" -nostartfiles --specs=nano.specs
                            --specs=nosys.specs -Wl,--gc-sections "-Wl,-Map=${CMAKE_BINARY_DIR}/out/hil_firmware.map")
        target_link_libraries(${name} PRIVATE m)
        target_include_directories(${name} PRIVATE "${board}")
    elseif(HIL_BOARD STREQUAL "stm32g474")
        set(board "${HIL_SDK}/boards/stm32g474")
        list(APPEND core "${board}/startup.c" "${board}/board.c" "${board}/fdcan.c")
        add_executable(${name} ${FW_SOURCES} ${core})
        set_target_properties(${name} PROPERTIES OUTPUT_NAME hil_firmware SUFFIX ".elf"
                              RUNTIME_OUTPUT_DIRECTORY "${CMAKE_BINARY_DIR}/out"
                              LINK_DEPENDS "${board}/stm32g474.ld")
        target_link_options(${name} PRIVATE "-T${board}/stm32g474.ld" -nostartfiles --specs=nano.specs
                            --specs=nosys.specs -Wl,--gc-sections "-Wl,-Map=${CMAKE_BINARY_DIR}/out/hil_firmware.map")
        target_link_libraries(${name} PRIVATE m)
        target_include_directories(${name} PRIVATE "${board}")
    else()
        message(FATAL_ERROR "HIL_BOARD must be host, mps2-an386 or stm32g474, got '${HIL_BOARD}'")
    endif()
    target_include_directories(${name} PRIVATE ${FW_INCLUDES} "${HIL_SDK}/target" "${HIL_SDK}/generated")
    if(HIL_DEFINES)
        target_compile_definitions(${name} PRIVATE ${HIL_DEFINES})
    endif()
    if(FW_STRICT)
        target_compile_options(${name} PRIVATE ${HIL_STRICT_FLAGS})
    else()
        target_compile_options(${name} PRIVATE ${HIL_USER_FLAGS})
        set_source_files_properties(${core} PROPERTIES COMPILE_OPTIONS "${HIL_STRICT_FLAGS}")
    endif()
endfunction()

function(hil_add_board_firmware name)
    cmake_parse_arguments(FW "CODEC" "LINKER_SCRIPT" "SOURCES;INCLUDES" ${ARGN})
    if(NOT HIL_BOARD STREQUAL "stm32g474")
        message(FATAL_ERROR "hil_add_board_firmware() builds for HIL_BOARD stm32g474, got '${HIL_BOARD}'")
    endif()
    if(NOT FW_LINKER_SCRIPT)
        message(FATAL_ERROR "hil_add_board_firmware(${name}): LINKER_SCRIPT is required")
    endif()
    set(srcs ${FW_SOURCES})
    if(FW_CODEC)
        list(APPEND srcs "${HIL_SDK}/generated/hil_protocol.c")
    endif()
    add_executable(${name} ${srcs})
    set_target_properties(${name} PROPERTIES OUTPUT_NAME hil_firmware SUFFIX ".elf"
                          RUNTIME_OUTPUT_DIRECTORY "${CMAKE_BINARY_DIR}/out" LINK_DEPENDS "${FW_LINKER_SCRIPT}")
    target_link_options(${name} PRIVATE "-T${FW_LINKER_SCRIPT}" -nostartfiles --specs=nano.specs
                        --specs=nosys.specs -Wl,--gc-sections "-Wl,-Map=${CMAKE_BINARY_DIR}/out/hil_firmware.map")
    target_link_libraries(${name} PRIVATE m)
    target_include_directories(${name} PRIVATE ${FW_INCLUDES})
    if(FW_CODEC)
        target_include_directories(${name} PRIVATE "${HIL_SDK}/generated")
    endif()
    if(HIL_DEFINES)
        target_compile_definitions(${name} PRIVATE ${HIL_DEFINES})
    endif()
    target_compile_options(${name} PRIVATE ${HIL_STRICT_FLAGS})
endfunction()
