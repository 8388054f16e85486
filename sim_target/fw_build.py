"""Builds a firmware of the HIL target core (docs/firmware_api.md) with CMake: the reference firmware
(firmware_stub/src behind firmware_stub/target/hil_app_reference.c) or a user's source folder, for the host
(a shared library for `--target sil:PATH`) or the emulated Cortex-M4F board mps2-an386 (an ELF for
`--target qemu:PATH`).

Builds go to a per-user cache folder (one per source folder and board, incremental, locked while in use);
`build_firmware` copies the artefact to `out` when given.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from pmsm_hil.sim_target.firmware import FirmwareError

FIRMWARE_DIR = Path(__file__).resolve().parent.parent / "firmware_stub"
REFERENCE_SRC = FIRMWARE_DIR / "target" / "reference"
BOARDS = ("host", "mps2-an386")
#: what each board needs besides cmake (and a host C compiler)
BOARD_TOOLS: dict[str, tuple[str, ...]] = {"host": ("cmake",), "mps2-an386": ("cmake", "arm-none-eabi-gcc")}
ARTEFACT = {"host": "libhil_firmware.so", "mps2-an386": "hil_firmware.elf"}
BUILD_TIMEOUT_S = 600.0


class FwBuildError(FirmwareError):
    """A firmware build could not run or failed (the message names the tool or the compiler's error)."""


@dataclass(frozen=True, slots=True)
class Sizes:
    """Section sizes of an ELF (arm-none-eabi-size, Berkeley format) [bytes]."""

    text: int
    data: int
    bss: int

    @property
    def flash(self) -> int:
        """Code, constants and the initial values of .data."""
        return self.text + self.data

    @property
    def ram(self) -> int:
        """Static RAM: .data + .bss (size counts the NOLOAD sections too: the 16 KiB stack reservation)."""
        return self.data + self.bss


@dataclass(frozen=True, slots=True)
class BuildResult:
    """The built artefact (in the build cache, or `out`), its board, and the ELF section sizes."""

    path: Path
    board: str
    src: Path
    sizes: Sizes | None = None


def missing_tools(board: str) -> list[str]:
    """Tools `board` needs that are not on PATH."""
    return [t for t in BOARD_TOOLS[board] if shutil.which(t) is None]


def cache_dir() -> Path:
    """Per-user cache of firmware builds and the QEMU plugin."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    path = Path(base) / "pmsm_hil"
    try:
        path.mkdir(parents=True, exist_ok=True)
        return path
    except OSError:
        path = Path(tempfile.gettempdir()) / f"pmsm_hil-{os.getuid()}"
        path.mkdir(parents=True, exist_ok=True)
        return path


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+b") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _run(cmd: list[str], what: str) -> None:
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=BUILD_TIMEOUT_S)
    except (OSError, subprocess.SubprocessError) as exc:
        raise FwBuildError(f"{what}: {exc}") from None
    if proc.returncode != 0:
        text = (proc.stderr.strip() or proc.stdout.strip()).splitlines()
        errors = [ln for ln in text if "error" in ln.lower()] or text
        raise FwBuildError(f"{what} failed: " + " | ".join(errors[:6])[:1500])


def elf_sizes(elf: Path) -> Sizes | None:
    """text/data/bss of an ELF via arm-none-eabi-size (None when the tool is missing)."""
    tool = shutil.which("arm-none-eabi-size") or shutil.which("size")
    if tool is None:
        return None
    proc = subprocess.run([tool, str(elf)], capture_output=True, text=True, timeout=60)
    lines = proc.stdout.strip().splitlines()
    if proc.returncode != 0 or len(lines) < 2:
        return None
    text, data, bss = (int(v) for v in lines[1].split()[:3])
    return Sizes(text, data, bss)


def build_firmware(board: str = "host", src: Path | None = None, out: Path | None = None,
                   *, jobs: int | None = None) -> BuildResult:
    """Configure and build `src` (a CMake folder using firmware_stub/target/hil_target.cmake; default: the
    reference firmware) for `board`; copy the artefact to `out` if given. Raises FwBuildError."""
    if board not in BOARDS:
        raise FwBuildError(f"--board must be one of {', '.join(BOARDS)}, got {board!r}")
    missing = missing_tools(board)
    if missing:
        hint = " (apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi)" if "arm-none-eabi-gcc" in missing else ""
        raise FwBuildError(f"building for {board} needs {', '.join(missing)} on PATH{hint}")
    src = (src or REFERENCE_SRC).resolve()
    if not (src / "CMakeLists.txt").is_file():
        raise FwBuildError(f"--src {src}: no CMakeLists.txt (see examples/my_firmware/)")
    key = hashlib.sha256(f"{src}\0{board}\0{FIRMWARE_DIR}".encode()).hexdigest()[:16]
    build = cache_dir() / "fw-build" / f"{src.name}-{board}-{key}"
    cmd = ["cmake", "-S", str(src), "-B", str(build), f"-DHIL_SDK={FIRMWARE_DIR}", f"-DHIL_BOARD={board}",
           "-DCMAKE_BUILD_TYPE=Release"]
    if board == "mps2-an386":
        cmd.append(f"-DCMAKE_TOOLCHAIN_FILE={FIRMWARE_DIR / 'boards' / 'mps2-an386' / 'toolchain.cmake'}")
    with _locked(build.with_suffix(".lock")):
        _run(cmd, f"cmake configure of {src}")
        _run(["cmake", "--build", str(build), "-j", str(jobs or os.cpu_count() or 1)], f"build of {src} for {board}")
        artefact = build / "out" / ARTEFACT[board]
        if not artefact.is_file():
            raise FwBuildError(f"build of {src} produced no {ARTEFACT[board]}: does its CMakeLists.txt call "
                                      "hil_add_firmware()?")
        if out is not None:
            artefact = _copy_out(artefact, Path(out), board)
    sizes = elf_sizes(artefact) if board != "host" else None
    return BuildResult(artefact, board, src, sizes)


def _copy_out(artefact: Path, out: Path, board: str) -> Path:
    """Copy the artefact to `out` (a file, or a folder for the artefact's own name) through a temporary file;
    FwBuildError naming -o if it cannot be written (/proc, a read-only folder, a full disk)."""
    if out.is_dir():
        out = out / ARTEFACT[board]
    tmp = out.with_name(out.name + ".tmp")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(artefact, tmp)
        os.replace(tmp, out)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise FwBuildError(f"-o {out}: cannot write the {ARTEFACT[board]} there ({exc.strerror or exc})") from None
    return out
