"""Small test firmwares for the virtual STM32G4 board, built with arm-none-eabi-gcc (skipped without it)."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from pmsm_hil.sim_target.stm32g4 import periph_native
from tests.board.fake_bus import FakeBus

FW = Path(__file__).with_name("fw")
GCC = "arm-none-eabi-gcc"
CFLAGS = ["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16", "-O2", "-g", "-std=c99", "-Wall",
          "-Wextra", "-Werror", "-ffreestanding", "-nostdlib", "-nostartfiles", "-fno-common"]


@pytest.fixture()
def bus() -> FakeBus:
    """A fresh fake board (a test module may define its own `bus`)."""
    return FakeBus()


@pytest.fixture(scope="module", params=[True, False], ids=["c_models", "python_models"])
def tim_adc_models(request: pytest.FixtureRequest) -> Iterator[bool]:
    """TIM1 and the ADCs in C, then their Python reference (periph_native.NATIVE): a module that uses this runs its
    tests with both."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(periph_native, "NATIVE", request.param)
        yield bool(request.param)


@pytest.fixture(scope="session")
def build_fw(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., Path]:
    """build_fw("core") -> the ELF of fw/core.c linked with fw/startup.c for the G474 (part="g431": the G431)."""
    if shutil.which(GCC) is None:
        pytest.skip(f"{GCC} not installed")
    out_dir = tmp_path_factory.mktemp("board-fw")
    built: dict[tuple[str, tuple[str, ...]], Path] = {}

    def build(name: str, *defines: str, part: str = "g474") -> Path:
        key = (name, (*defines, part))
        if key not in built:
            elf = out_dir / f"{name}{'-'.join(('', *defines))}-{part}.elf"
            cmd = [GCC, *CFLAGS, *(f"-D{d}" for d in defines), "-T", str(FW / f"{part}.ld"), "-o", str(elf),
                   str(FW / "startup.c"), str(FW / f"{name}.c"), "-lgcc"]
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
            assert proc.returncode == 0, proc.stderr
            built[key] = elf
        return built[key]

    return build
