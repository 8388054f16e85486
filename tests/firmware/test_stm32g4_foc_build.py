"""`hil fw build --board stm32g474` builds examples/stm32g4_foc (arm-none-eabi-gcc, strict flags) and the ELF is an
STM32G474 image: the vector table at 0x08000000 with the initial stack at the top of SRAM and the handlers of the
interrupts the firmware uses at their RM0440 positions; the LATE_ISR and FAULT variants build too."""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path

import pytest

from pmsm_hil.sim_target.elf import elf_object, elf_symbols
from pmsm_hil.sim_target.fw_build import BuildResult, FwBuildError, build_firmware, missing_tools

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "stm32g4_foc"
FLASH = 0x08000000
SRAM_END = 0x20000000 + 96 * 1024
#: (vector position, handler): 16 system exceptions, then IRQ n at 16 + n (RM0440 Table 97)
HANDLERS = {1: "Reset_Handler", 3: "HardFault_Handler", 5: "BusFault_Handler", 15: "SysTick_Handler",
            16 + 18: "ADC1_2_IRQHandler", 16 + 21: "FDCAN1_IT0_IRQHandler"}


def _need() -> None:
    missing = missing_tools("stm32g474")
    if missing:
        pytest.skip(f"firmware board stm32g474: {', '.join(missing)} not installed")


@pytest.fixture(scope="module")
def built() -> BuildResult:
    _need()
    return build_firmware("stm32g474")


def test_default_source_of_the_board_is_the_example(built: BuildResult) -> None:
    assert built.src == EXAMPLE.resolve()
    assert built.path.name == "hil_firmware.elf" and built.path.is_file()
    assert built.warnings == ()  # -Wall -Wextra -Werror: a warning would have failed the build anyway
    assert built.sizes is not None and 0 < built.sizes.flash < 512 * 1024


def test_vector_table_at_flash_start_names_the_handlers(built: BuildResult) -> None:
    syms = elf_symbols(built.path)
    assert syms["g_pfnVectors"] == FLASH
    table = elf_object(built.path, "g_pfnVectors")
    assert table is not None and len(table) == 4 * (16 + 102)
    words = struct.unpack(f"<{16 + 102}I", table)
    assert words[0] == SRAM_END  # initial main stack pointer: top of SRAM1 + SRAM2
    for pos, name in HANDLERS.items():
        assert words[pos] == syms[name], name
        assert words[pos] & 1, f"{name}: a Thumb address"
    default = syms["Default_Handler"]
    assert words[16 + 38] == default  # USART2: polled, not an interrupt of this firmware
    assert words[16 + 85] == 0  # IRQ 85 is reserved on the G474


def test_control_state_lives_in_ccm_sram(built: BuildResult) -> None:
    assert 0x10000000 <= elf_symbols(built.path)["g"] < 0x10000000 + 32 * 1024


@pytest.mark.parametrize("variant", ["LATE_ISR", "FAULT", "FW_NO_BUS"])
def test_variants_build(variant: str) -> None:
    _need()
    result = build_firmware("stm32g474", defines=[variant])
    syms = elf_symbols(result.path)
    assert "ADC1_2_IRQHandler" in syms and result.warnings == ()


def test_cli_prints_the_elf_path() -> None:
    _need()
    proc = subprocess.run([sys.executable, "-m", "pmsm_hil.app.cli.main", "fw", "build", "--board", "stm32g474"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("built "))
    assert Path(line.split()[1]).is_file() and line.split()[1].endswith(".elf")


def test_target_core_firmware_builds_on_the_boards_firmware_api_layer() -> None:
    """hil_add_firmware() on stm32g474: the target core on firmware_stub/boards/stm32g474/ (FDCAN1), not refused."""
    from pmsm_hil.sim_target.elf import elf_symbols

    _need()
    symbols = elf_symbols(build_firmware("stm32g474", ROOT / "examples" / "my_firmware").path)
    assert {"hil_core_rx", "hil_app_step", "FDCAN1_IT0_IRQHandler"} <= set(symbols)


def test_vendor_header_folder_without_the_header_is_refused(tmp_path: Path) -> None:
    _need()
    with pytest.raises(FwBuildError, match=r"no stm32g474xx\.h"):
        build_firmware("stm32g474", defines=[f"VENDOR_DEVICE_INCLUDE={tmp_path}",
                                             f"VENDOR_CMSIS_INCLUDE={tmp_path}"])
