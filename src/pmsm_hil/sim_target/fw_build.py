"""Builds a firmware of the HIL target core (docs/firmware_api.md) with CMake: the reference firmware
(firmware_stub/src behind firmware_stub/target/hil_app_reference.c) or a user's source folder, for the host
(a shared library for `--target sil:PATH`), the emulated Cortex-M4F board mps2-an386 (an ELF for
`--target qemu:PATH`), or the STM32G474 (an ELF for a real board and for `--target stm32g4:PATH`: the target core
on firmware_stub/boards/stm32g474/, or a bare-metal firmware; default source examples/stm32g4_foc).

Builds go to a per-user cache folder (one per source folder, board and set of `--define`s, incremental, locked
while in use), and each built firmware into the content-keyed cache (`fw_cache`): the same sources, SDK, board,
defines and tools found again build nothing, from any folder; `build_firmware` copies the artefact to `out` when
given. What the compiler said is kept: the
warnings of a build that succeeded (`BuildResult.warnings`), and of one that failed the key lines
(`key_lines`: undefined references, the first error with its caret context) in the FwBuildError.

A firmware that built but whose parameter table is refused is cached like any other and refused again when found
(the check reads the cached bytes). A failed compile or link is not cached: CMake runs again. Its inputs are not all
known (a missing header may be created outside the keyed folders, where nothing records it was looked for) and a
failure may be the machine's (a full disk, a killed compiler, a timeout): a replayed failure could outlive its cause.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from pmsm_hil.sim_target.firmware import FirmwareError

FIRMWARE_DIR = Path(__file__).resolve().parents[3] / "firmware_stub"
REFERENCE_SRC = FIRMWARE_DIR / "target" / "reference"
#: the example firmware for the virtual STM32G474 (the default source of `--board stm32g474`)
STM32G4_EXAMPLE_SRC = FIRMWARE_DIR.parent / "examples" / "stm32g4_foc"
BOARDS = ("host", "mps2-an386", "stm32g474")
#: boards whose firmware is an ARM ELF built with a toolchain file of firmware_stub/boards/<board>/
MCU_BOARDS = ("mps2-an386", "stm32g474")
#: what each board needs besides cmake (and a host C compiler)
BOARD_TOOLS: dict[str, tuple[str, ...]] = {"host": ("cmake",), "mps2-an386": ("cmake", "arm-none-eabi-gcc"),
                                           "stm32g474": ("cmake", "arm-none-eabi-gcc")}
ARTEFACT = {"host": "libhil_firmware.so", "mps2-an386": "hil_firmware.elf", "stm32g474": "hil_firmware.elf"}
BUILD_TIMEOUT_S = 600.0
#: warning lines a build result shows (their count is always given)
SHOWN_WARNINGS = 5
#: `--define NAME=VALUE`: NAME a C identifier
_DEFINE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_WARNING = re.compile(r": warning: ")
_ERROR = re.compile(r"(: (fatal )?error: )|(^CMake Error)|(\berror: ld returned)")
_UNDEFINED = re.compile(r"undefined reference to|undefined symbol")


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
    #: the compiler's warning lines (as printed, without their context lines)
    warnings: tuple[str, ...] = ()


def missing_tools(board: str) -> list[str]:
    """Tools `board` needs that are not on PATH."""
    return [t for t in BOARD_TOOLS[board] if shutil.which(t) is None]


def cache_dir() -> Path:
    """Per-user cache of firmware builds and of the host libraries (QEMU plugin, instruction counter)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    path = Path(base) / "pmsm_hil"
    try:
        path.mkdir(parents=True, exist_ok=True)
        return path
    except OSError:
        path = Path(tempfile.gettempdir()) / f"pmsm_hil-{os.getuid()}"
        path.mkdir(parents=True, exist_ok=True)
        return path


def host_library(source: Path, stem: str, what: str, error: type[FirmwareError], *, werror: bool = True) -> Path:
    """`source` compiled by the host C compiler into a shared library in the cache, keyed by the source's hash
    (built on first use); `what` names it in `error`'s message when there is no compiler or it fails."""
    out = cache_dir() / f"{stem}-{hashlib.sha256(source.read_bytes()).hexdigest()[:16]}.so"
    if out.is_file():
        return out
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise error(f"{what} needs a host C compiler (cc)")
    tmp = out.with_name(f"{out.name}.{os.getpid()}.tmp")
    flags = ["-shared", "-fPIC", "-O2", "-Wall", "-Wextra", *(["-Werror"] if werror else [])]
    proc = subprocess.run([cc, *flags, "-o", str(tmp), str(source)], capture_output=True, text=True, timeout=120)
    if proc.returncode != 0:
        raise error(f"{what} build failed: {proc.stderr.strip()[:500]}")
    os.replace(tmp, out)
    return out


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+b") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def key_lines(text: str, *, limit: int = 12) -> list[str]:
    """What a failed build's output says broke: every undefined reference (the missing function named), then
    the first compiler error with the lines after it that show the source and the caret; else the error lines;
    else the output's last lines."""
    lines = [ln.rstrip() for ln in text.splitlines()]
    undefined = [ln.strip() for ln in lines if _UNDEFINED.search(ln)]
    out = list(dict.fromkeys(undefined))
    first = next((i for i, ln in enumerate(lines) if _ERROR.search(ln) and not _UNDEFINED.search(ln)
                  and "ld returned" not in ln and "collect2" not in ln), None)
    if first is not None:
        out.append(lines[first].strip())
        if lines[first].startswith("CMake Error"):  # the message follows, indented, up to an empty line
            body = lines[first + 1:first + 8]
            while body and not body[0].strip():
                body.pop(0)
            for ln in body:
                if not ln.strip():
                    break
                out.append(ln.strip())
        for ln in lines[first + 1:first + 4]:  # "   12 |   code" and "      |   ^~~~"
            if re.match(r"\s*\d*\s*\|", ln):
                out.append(ln)
            else:
                break
    if not out:
        out = [ln.strip() for ln in lines if "error" in ln.lower()] or [ln for ln in lines if ln.strip()][-6:]
    return out[:limit]


def warning_lines(text: str) -> list[str]:
    """The compiler's warning lines (each once, in order)."""
    return list(dict.fromkeys(ln.strip() for ln in text.splitlines() if _WARNING.search(ln)))


def _run(cmd: list[str], what: str, *, verbose: bool = False, on_line: Callable[[str], None] | None = None) -> str:
    """Run a build step; its whole output (stdout + stderr), echoed to stderr when `verbose`, each line given to
    `on_line` as it comes (a status line) when given."""
    if verbose:
        print("+ " + " ".join(cmd), file=sys.stderr, flush=True)
    try:
        if on_line is None:
            proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                  timeout=BUILD_TIMEOUT_S)
            returncode, output = proc.returncode, proc.stdout
        else:
            returncode, output = _run_streaming(cmd, on_line)
    except (OSError, subprocess.SubprocessError) as exc:
        raise FwBuildError(f"{what}: {exc}") from None
    if verbose and output:
        print(output, file=sys.stderr, end="" if output.endswith("\n") else "\n", flush=True)
    if returncode != 0:
        lines = key_lines(output)
        raise FwBuildError(f"{what} failed:\n    " + "\n    ".join(lines) + "\n(`hil fw build --verbose` shows "
                           "the whole output)")
    return output


def _run_streaming(cmd: list[str], on_line: Callable[[str], None]) -> tuple[int, str]:
    """`cmd`'s exit code and output (stdout + stderr), each line given to `on_line` as it comes; killed after
    BUILD_TIMEOUT_S (subprocess.TimeoutExpired)."""
    import threading

    killed: list[bool] = []
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) as proc:
        def kill() -> None:
            killed.append(True)
            proc.kill()

        timer = threading.Timer(BUILD_TIMEOUT_S, kill)
        timer.start()
        lines: list[str] = []
        try:
            assert proc.stdout is not None
            for line in proc.stdout:
                lines.append(line)
                on_line(line.rstrip("\n"))
            returncode = proc.wait()
        finally:
            timer.cancel()
    if killed:
        raise subprocess.TimeoutExpired(cmd, BUILD_TIMEOUT_S)
    return returncode, "".join(lines)


def _remember_warnings(build: Path, output: str) -> tuple[str, ...]:
    """The warnings of the firmware as built now: those of the sources compiled by this build, and for the sources
    not compiled again (an up-to-date build, or a partial rebuild after another file changed) those of the build
    that last compiled them (kept in the build folder), so a warning does not vanish on the next `hil fw build`."""
    store = build / "hil_warnings.txt"
    compiled = [m.group(1) for m in _COMPILED.finditer(output)]
    found = warning_lines(output)
    kept: list[str] = []
    with contextlib.suppress(OSError):
        kept = [ln for ln in store.read_text().splitlines() if ln]
    if compiled:
        kept = [ln for ln in kept if not any(obj.endswith(ln.split(":", 1)[0].lstrip("/")) for obj in compiled)]
        with contextlib.suppress(OSError):
            store.write_text("".join(w + "\n" for w in [*kept, *found]))
    return tuple(dict.fromkeys([*kept, *found]))


#: an object a build compiled: "Building C object CMakeFiles/T.dir/<source path>.o" → the source path
_COMPILED = re.compile(r"Building (?:C|CXX|ASM) object \S+?\.dir/(\S+)\.o\b")


def parse_defines(items: list[str] | None) -> tuple[str, ...]:
    """`--define NAME=VALUE` (or NAME alone: 1) items, validated; FwBuildError naming the item otherwise."""
    out: list[str] = []
    for item in items or []:
        name, sep, value = item.partition("=")
        if not _DEFINE_NAME.fullmatch(name):
            raise FwBuildError(f"--define {item!r}: NAME must be a C identifier (NAME=VALUE)")
        if "\n" in value or ";" in value:
            raise FwBuildError(f"--define {item!r}: VALUE must be one line without ';'")
        out.append(f"{name}={value}" if sep else f"{name}=1")
    return tuple(out)


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
                   *, jobs: int | None = None, defines: list[str] | tuple[str, ...] = (),
                   verbose: bool = False, progress: Callable[[str, str], None] | None = None,
                   use_cache: bool = True) -> BuildResult:
    """Configure and build `src` (a CMake folder using firmware_stub/target/hil_target.cmake; default: the
    reference firmware; for stm32g474 examples/stm32g4_foc) for `board`; copy the artefact to `out` if given.
    `defines` ("NAME=VALUE") become CMake variables and preprocessor macros of the firmware (hil_target.cmake
    HIL_DEFINES); `verbose` echoes the commands and the whole build output to stderr. Raises FwBuildError.
    A firmware built before from the same content (`fw_cache`: the sources, the SDK, board, defines, tools) is
    taken from the cache without running CMake, unless `verbose` or not `use_cache` (then CMake runs, an
    incremental build, and the cache entry is made again). `progress(step, line)` (a status line) is told each
    step (`cached`; or `configuring`, `building`) and, while building, each line of the output as it comes."""
    def step(name: str, line: str = "") -> None:
        if progress is not None:
            progress(name, line)

    if board not in BOARDS:
        raise FwBuildError(f"--board must be one of {', '.join(BOARDS)}, got {board!r}")
    missing = missing_tools(board)
    if missing:
        hint = " (apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi)" if "arm-none-eabi-gcc" in missing else ""
        raise FwBuildError(f"building for {board} needs {', '.join(missing)} on PATH{hint}")
    src = (src or (STM32G4_EXAMPLE_SRC if board == "stm32g474" else REFERENCE_SRC)).resolve()
    if not (src / "CMakeLists.txt").is_file():
        raise FwBuildError(f"--src {src}: no CMakeLists.txt (see examples/my_firmware/)")
    defs = parse_defines(list(defines))
    from pmsm_hil.sim_target import fw_cache

    entry = fw_cache.entry_dir(src, board, fw_cache.content_key(src, FIRMWARE_DIR, board, defs,
                                                                mcu=board in MCU_BOARDS))
    with fw_cache.lock(entry):
        found = None if (verbose or not use_cache) else fw_cache.find(entry, ARTEFACT[board], src, FIRMWARE_DIR)
        if found is not None:
            step("cached")
            artefact, warnings = found.artefact, found.warnings
            sizes = None if found.sizes is None else Sizes(*found.sizes)
        else:
            build, artefact, warnings = _cmake_build(board, src, defs, jobs=jobs, verbose=verbose, progress=progress)
            sizes = elf_sizes(artefact) if board != "host" else None
            artefact = fw_cache.store(entry, artefact, warnings,
                                      None if sizes is None else (sizes.text, sizes.data, sizes.bss),
                                      fw_cache.outside_inputs(build, src, FIRMWARE_DIR), src, FIRMWARE_DIR)
    _check_param_table(artefact)  # built now or found: the same bytes give the same verdict
    if out is not None:
        artefact = _copy_out(artefact, Path(out), board)
    return BuildResult(artefact, board, src, sizes, warnings)


def _cmake_build(board: str, src: Path, defs: tuple[str, ...], *, jobs: int | None, verbose: bool,
                 progress: Callable[[str, str], None] | None) -> tuple[Path, Path, tuple[str, ...]]:
    """Configure and build `src` in its build folder (one per source folder, board and defines: incremental);
    the folder, the artefact in it and the warnings (its parameter table is checked by the caller)."""
    key = hashlib.sha256("\0".join((str(src), board, str(FIRMWARE_DIR), *defs)).encode()).hexdigest()[:16]
    build = cache_dir() / "fw-build" / f"{src.name}-{board}-{key}"
    cmd = ["cmake", "-S", str(src), "-B", str(build), f"-DHIL_SDK={FIRMWARE_DIR}", f"-DHIL_BOARD={board}",
           "-DCMAKE_BUILD_TYPE=Release", f"-DHIL_DEFINES={';'.join(defs)}", *(f"-D{d}" for d in defs)]
    if board in MCU_BOARDS:
        cmd.append(f"-DCMAKE_TOOLCHAIN_FILE={FIRMWARE_DIR / 'boards' / board / 'toolchain.cmake'}")
    build_cmd = ["cmake", "--build", str(build), "-j", str(jobs or os.cpu_count() or 1)]
    if verbose:
        build_cmd.append("--verbose")
    with _locked(build.with_suffix(".lock")):
        if progress is not None:
            progress("configuring", "")
        _run(cmd, f"cmake configure of {src}", verbose=verbose)
        if progress is not None:
            progress("building", "")
        output = _run(build_cmd, f"build of {src} for {board}", verbose=verbose,
                      on_line=None if progress is None else lambda line: progress("building", line))
        warnings = _remember_warnings(build, output)
        artefact = build / "out" / ARTEFACT[board]
        if not artefact.is_file():
            call = "hil_add_board_firmware()" if board == "stm32g474" else "hil_add_firmware()"
            raise FwBuildError(f"build of {src} produced no {ARTEFACT[board]}: does its CMakeLists.txt call "
                               f"{call}?")
    return build, artefact, warnings


def _check_param_table(artefact: Path) -> None:
    """FwBuildError naming the entry if the firmware's parameter table (`hil_app_params`, hil_app_params.h) is
    malformed: a name or unit not NUL-terminated, an id outside 128..254, a non-finite default or range, ...
    (checked when it is built or found in the cache, not first when a run reads it)."""
    from pmsm_hil.sim_target.fw_params import FirmwareParamError, firmware_params

    try:
        firmware_params(artefact)
    except FirmwareParamError as exc:
        raise FwBuildError(f"{exc} (hil_app_params.h)") from None


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
