"""The emulated MCU target: a firmware of the HIL target core built for mps2-an386 (`hil fw build --board
mps2-an386`, a Cortex-M4F ELF) running in QEMU, started and stopped by the host.

Lockstep and deterministic: QEMU runs with `-icount` (virtual time advances a fixed 2^shift ns per
instruction), the firmware waits for frames with WFI, and the host's serial link (COBS + CRC-16) talks to the
emulated CMSDK UART0 through a Unix socket (`-chardev socket,...,server=on -serial chardev:...`).

The faster transport (`transport="mailbox"`): frames in the board's PSRAM, backed by a file shared with the host,
and two host FIFOs as doorbells that the firmware reads and writes with Arm semihosting calls (blocking QEMU's
vCPU thread in read(2) until the host rings): neither end spins, so the pair does not stall for scheduler time
slices on a busy machine (docs/firmware_api.md, docs/benchmarks.md).

Guest progress: the plugin's running instruction count lives in a file mapped by both QEMU and the host
(`progress_address`): in lockstep the host judges the guest by its own progress, not by QEMU's CPU time
(src/pmsm_hil/hil/runner/c/loop_stall.h `nl_guest_available`, docs/runner.md "Host stalls").

Execution cost: a QEMU TCG plugin (firmware_stub/boards/mps2-an386/qemu/hil_insn_plugin.c, built on first
use) counts the instructions between the firmware's step markers exactly; `metrics()` turns the counts of the
metrics window into `exec_instructions` and the estimate `exec_time_us` at `mcu_clock_hz` with the cycle
model below. The firmware itself reads SysTick (which under -icount counts virtual time, so instructions) and
reports the same estimate per period in each Command's exec_time_ns.

QEMU never outlives the host: it gets PR_SET_PDEATHSIG(SIGKILL) before exec, and `close()` (every exit path
of the runner) terminates it.
"""

from __future__ import annotations

import contextlib
import ctypes
import mmap
import os
import re
import select
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from array import array
from collections import deque
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pmsm_hil.protocol.errors import LinkError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links.stats import LinkStats
from pmsm_hil.sim_target.elf import ElfError, elf_function_at, elf_symbols
from pmsm_hil.sim_target.firmware import FirmwareError
from pmsm_hil.sim_target.fw_build import FIRMWARE_DIR, host_library

QEMU = "qemu-system-arm"
MACHINE = "mps2-an386"
#: -icount shift: 2^6 = 64 ns of virtual time per instruction, so SysTick (25 MHz) ticks 1.6 times per
#: instruction and the firmware's own reading resolves single instructions
ICOUNT_SHIFT = 6
DEFAULT_MCU_CLOCK_HZ = 168e6
#: Cycle model of the estimate: cycles = instructions × CPI. CPI 1 is the Cortex-M4's issue rate (one
#: instruction per cycle, zero-wait-state memory); loads, taken branches, divides, square roots and flash wait
#: states add cycles on a real part, so the estimate is a lower bound (typically 1.2-1.5x on real hardware).
CPI = 1.0
CYCLE_MODEL = (f"estimate: instructions counted exactly in QEMU (mps2-an386, Cortex-M4F) x {CPI:g} cycle per "
               "instruction at the MCU clock (zero-wait-state lower bound; real parts add cycles for loads, taken "
               "branches, divides and flash wait states)")
PLUGIN_SRC = FIRMWARE_DIR / "boards" / "mps2-an386" / "qemu" / "hil_insn_plugin.c"
START_TIMEOUT_S = 20.0
_PR_SET_PDEATHSIG = 1
CFG_MAGIC = 0x48494C43
#: transports: the emulated UART (default, WFI on its RX interrupt) or the PSRAM mailbox (busy-polled)
TRANSPORTS = ("uart", "mailbox")
#: the board's PSRAM (QEMU machine RAM, 16 MiB at 0x21000000): its backing file is the mailbox
PSRAM_SIZE = 16 << 20
MBOX_H2T_SEQ, MBOX_H2T_LEN, MBOX_T2H_SEQ, MBOX_T2H_LEN = 0x000, 0x004, 0x008, 0x00C
MBOX_H2T_BUF, MBOX_T2H_BUF, MBOX_BUF_SIZE = 0x040, 0x440, 0x400
MAILBOX_TIMEOUT_S = 5.0
#: longest single sleep on the doorbell [ms] (the caller's deadlines are checked between sleeps)
WAIT_SLICE_MS = 2
#: doorbell FIFO paths in the PSRAM (offsets, size; firmware_stub/boards/mps2-an386/board.h)
MBOX_H2T_PATH, MBOX_T2H_PATH, MBOX_PATH_SIZE = 0x840, 0x940, 0x100


#: QEMU's exit code after the firmware faulted: FAULT_EXIT_BASE + the exception number (board.h,
#: HIL_BOARD_FAULT_EXIT_BASE; startup.c ends QEMU through semihosting SYS_EXIT_EXTENDED)
FAULT_EXIT_BASE = 64
FAULT_NAMES = {3: "HardFault", 4: "MemManage fault", 5: "BusFault", 6: "UsageFault"}


#: the fault handler's report line on the semihosting console (startup.c hil_fault_report)
_FAULT_LINE = re.compile(r"HIL-FAULT exc=(\d+) pc=([0-9a-f]{8}) lr=([0-9a-f]{8}) cfsr=([0-9a-f]{8}) "
                         r"hfsr=([0-9a-f]{8}) mmfar=([0-9a-f]{8}) bfar=([0-9a-f]{8})")
#: CFSR bits (Armv7-M: MMFSR 0-7, BFSR 8-15, UFSR 16-31) and HFSR bits, as the Arm reference manual names them
CFSR_BITS = {0: "IACCVIOL", 1: "DACCVIOL", 3: "MUNSTKERR", 4: "MSTKERR", 5: "MLSPERR", 7: "MMARVALID",
             8: "IBUSERR", 9: "PRECISERR", 10: "IMPRECISERR", 11: "UNSTKERR", 12: "STKERR", 13: "LSPERR",
             15: "BFARVALID", 16: "UNDEFINSTR", 17: "INVSTATE", 18: "INVPC", 19: "NOCP", 24: "UNALIGNED",
             25: "DIVBYZERO"}
HFSR_BITS = {1: "VECTTBL", 30: "FORCED", 31: "DEBUGEVT"}


def _bits(value: int, names: dict[int, str]) -> str:
    found = [name for bit, name in names.items() if value >> bit & 1]
    return f" ({' '.join(found)})" if found else ""


def describe_fault(report: str, elf: str | Path | None = None) -> str | None:
    """"HardFault at pc 0x... (function+0xOFF), lr 0x... (function+0xOFF), CFSR 0x... (bits), HFSR 0x... (bits)"
    from the fault handler's report line in `report` (QEMU's stderr), the functions named from `elf`'s symbols;
    None when `report` holds no such line."""
    match = _FAULT_LINE.search(report)
    if match is None:
        return None
    exc, pc, lr, cfsr, hfsr, mmfar, bfar = (int(g, 10 if i == 0 else 16) for i, g in enumerate(match.groups()))

    def where(addr: str, value: int) -> str:
        name = None
        if elf is not None:
            with contextlib.suppress(ElfError, OSError):
                name = elf_function_at(elf, value)
        return f"{addr} {value:#010x}" + (f" ({name})" if name else "")

    text = (f"{FAULT_NAMES.get(exc, f'fault exception {exc}')} at {where('pc', pc)}, {where('lr', lr)}, "
            f"CFSR {cfsr:#010x}{_bits(cfsr, CFSR_BITS)}, HFSR {hfsr:#010x}{_bits(hfsr, HFSR_BITS)}")
    if cfsr >> 7 & 1:
        text += f", MMFAR {mmfar:#010x}"
    if cfsr >> 15 & 1:
        text += f", BFAR {bfar:#010x}"
    return text


def fault_name(returncode: int) -> str | None:
    """The fault a QEMU exit code reports ("HardFault", ...), None when it reports none."""
    exc = returncode - FAULT_EXIT_BASE
    if exc in FAULT_NAMES:
        return FAULT_NAMES[exc]
    return f"fault exception {exc}" if 0 < exc < 16 else None


class QemuError(FirmwareError):
    """QEMU or the plugin compiler is missing, the ELF lacks the core's symbols, or QEMU did not start."""


def qemu_available() -> str:
    """'' when qemu-system-arm and a host C compiler are on PATH, else what is missing."""
    missing = [t for t in (QEMU,) if shutil.which(t) is None]
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        missing.append("cc")
    return ", ".join(missing)


def plugin_path() -> Path:
    """The instruction-count plugin, compiled on first use into the cache (keyed by its source)."""
    return host_library(PLUGIN_SRC, "hil_insn_plugin", "the instruction-count plugin", QemuError, werror=False)


def _die_with_parent() -> None:  # pragma: no cover - runs in the child between fork and exec
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)


def stats(values: np.ndarray) -> dict[str, float]:
    """{median, p99, max} of a sample (numbers)."""
    return {"median": float(np.median(values)), "p99": float(np.percentile(values, 99)), "max": float(values.max())}


class QemuTarget:
    """One QEMU process running `elf`; `link_spec` is the host's end of the emulated UART0."""

    def __init__(self, elf: str | Path, *, mcu_clock_hz: float = DEFAULT_MCU_CLOCK_HZ, count_instructions: bool = True,
                 skip_steps: int = 0, transport: str = "uart") -> None:
        self.elf = Path(elf)
        if not self.elf.is_file():
            raise QemuError(f"qemu target: {self.elf} not found (build one with `hil fw build --board mps2-an386`)")
        missing = qemu_available()
        if missing:
            raise QemuError(f"qemu target needs {missing} on PATH (apt-get install qemu-system-arm)")
        try:
            syms = elf_symbols(self.elf)
        except (ElfError, OSError) as exc:
            raise QemuError(f"qemu target: {exc}") from None
        needed = ("hil_core_step_begin", "hil_core_step_end", "hil_board_cfg")
        lacking = [n for n in needed if n not in syms]
        if lacking:
            raise QemuError(f"qemu target: {self.elf} lacks {', '.join(lacking)} (not a HIL target core firmware "
                            "for mps2-an386?)")
        if not (1e6 <= mcu_clock_hz <= 2e9):
            raise QemuError(f"--mcu-clock must be between 1 MHz and 2 GHz, got {mcu_clock_hz:g} Hz")
        if transport not in TRANSPORTS:
            raise QemuError(f"qemu transport must be one of {', '.join(TRANSPORTS)}, got {transport!r}")
        self.mcu_clock_hz = float(mcu_clock_hz)
        self.skip_steps = skip_steps
        self.transport = transport
        self._dir = Path(tempfile.mkdtemp(prefix="hil-qemu-"))
        self.socket_path = self._dir / "uart0.sock"
        self.counts_path: Path | None = self._dir / "insns.u32" if count_instructions else None
        #: the plugin's running instruction count (first 8 bytes, native order), mapped here while QEMU runs
        self.progress_path: Path | None = self._dir / "progress.u64" if count_instructions else None
        self._progress_map: mmap.mmap | None = None
        self._progress: ctypes.c_uint64 | None = None
        self.process: subprocess.Popen[bytes] | None = None
        self._stderr = open(self._dir / "qemu.stderr", "w+b")  # noqa: SIM115 (closed in close())
        self._sock: socket.socket | None = None
        self.psram_path = self._dir / "psram"
        cfg_addr = syms["hil_board_cfg"]
        cmd = [QEMU, "-M", MACHINE, "-nodefaults", "-display", "none", "-monitor", "none",
               "-chardev", f"socket,id=uart0,path={self.socket_path},server=on,wait=off",
               "-serial", "chardev:uart0", "-icount", f"shift={ICOUNT_SHIFT},align=off",
               "-kernel", str(self.elf)]
        self._bells: tuple[int, int] | None = None
        if transport == "mailbox":
            self._bells = self._make_bells()
            cmd[2:3] = [f"{MACHINE},memory-backend=psram", "-object",
                        f"memory-backend-file,id=psram,size={PSRAM_SIZE},mem-path={self.psram_path},share=on",
                        "-semihosting-config", "enable=on,target=native"]
        else:  # semihosting for the fault handler's exit (the mailbox has it for its doorbells)
            cmd += ["-semihosting-config", "enable=on,target=native"]
        cfg_words = (CFG_MAGIC, round(self.mcu_clock_hz), 1 << ICOUNT_SHIFT, round(CPI * 1000),
                     TRANSPORTS.index(transport), 1)  # the last: fault_exit
        for offset, value in enumerate(cfg_words):
            cmd += ["-device", f"loader,addr={cfg_addr + 4 * offset:#x},data={value},data-len=4"]
        if self.counts_path is not None:
            begin, end = syms["hil_core_step_begin"] & ~1, syms["hil_core_step_end"] & ~1
            cmd += ["-plugin", f"{plugin_path()},begin={begin:#x},end={end:#x},out={self.counts_path},"
                    f"live={self.progress_path}"]
        self.command = cmd
        try:
            self._map_progress()
            self.process = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                            stderr=self._stderr, preexec_fn=_die_with_parent)
            self._sock = self._connect()
        except BaseException:
            self.close()
            raise

    def _map_progress(self) -> None:
        """Create the progress file (one page of zeros: the plugin maps the same page) and map it here."""
        if self.progress_path is None:
            return
        with open(self.progress_path, "w+b") as fh:
            fh.truncate(mmap.PAGESIZE)
            self._progress_map = mmap.mmap(fh.fileno(), mmap.PAGESIZE)
        self._progress = ctypes.c_uint64.from_buffer(self._progress_map)

    @property
    def ns_per_instruction(self) -> int:
        """Virtual time of one guest instruction [ns] (-icount shift)."""
        return 1 << ICOUNT_SHIFT

    def progress_address(self) -> int:
        """Address (in this process) of the guest's running instruction count, a u64 the plugin adds to as
        the guest executes; 0 without the plugin. Valid until `close()`."""
        return ctypes.addressof(self._progress) if self._progress is not None else 0

    def executed_instructions(self) -> int | None:
        """Instructions the guest executed so far; None without the plugin."""
        return int(self._progress.value) if self._progress is not None else None

    def _make_bells(self) -> tuple[int, int]:
        """The PSRAM file with the doorbell FIFO paths in it, and the host's ends of the two FIFOs (opened
        read-write, so neither open blocks nor the firmware's open of the other end; non-blocking)."""
        paths = (self._dir / "bell_h2t", self._dir / "bell_t2h")
        with open(self.psram_path, "wb") as fh:
            fh.truncate(PSRAM_SIZE)
            for offset, path in zip((MBOX_H2T_PATH, MBOX_T2H_PATH), paths, strict=True):
                raw = os.fsencode(path)
                if len(raw) >= MBOX_PATH_SIZE:
                    raise QemuError(f"qemu target: temporary path too long for the mailbox: {path}")
                fh.seek(offset)
                fh.write(raw + b"\0")
        fds: list[int] = []
        for path in paths:
            os.mkfifo(path, 0o600)
            fds.append(os.open(path, os.O_RDWR | os.O_NONBLOCK | os.O_CLOEXEC))
        return fds[0], fds[1]

    def _connect(self) -> socket.socket:
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:
            assert self.process is not None
            if self.process.poll() is not None:
                raise QemuError(f"QEMU exited with code {self.process.returncode}: {self._stderr_text()[-500:]}")
            if self.socket_path.exists():
                sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                try:
                    sock.connect(str(self.socket_path))
                    return sock
                except OSError:
                    sock.close()
            if time.monotonic() > deadline:
                raise QemuError(f"QEMU did not open its UART socket within {START_TIMEOUT_S:g} s")
            time.sleep(0.005)

    def stderr_tail(self, chars: int = 300) -> str:
        """The end of what QEMU wrote to its stderr, on one line (without its start-up warning about the
        board's unconnected network card)."""
        lines = [line for line in self._stderr_text().splitlines() if "has no peer" not in line]
        return " ".join(" ".join(lines)[-chars:].split())

    def fault_description(self, returncode: int) -> str | None:
        """What the firmware's fault handler reported ("HardFault at pc 0x... (hil_app_step+0x1c), ..."), or the
        fault the exit code names when the report line is missing; None when `returncode` is no fault exit."""
        name = fault_name(returncode)
        if name is None:
            return None
        return describe_fault(self._stderr_text(), self.elf) or name

    def console_text(self) -> str:
        """Everything QEMU wrote to its stderr so far (the semihosting console: the fault handler's report)."""
        return self._stderr_text()

    def _stderr_text(self) -> str:
        with contextlib.suppress(OSError, ValueError):
            self._stderr.flush()
            self._stderr.seek(0)
            return self._stderr.read().decode(errors="replace").strip()
        return ""

    def mailbox_link(self) -> MailboxLink:
        """The host's end of the PSRAM mailbox (transport 'mailbox')."""
        if self.transport != "mailbox":
            raise QemuError("this QEMU target runs the UART transport: use link_spec")
        assert self._bells is not None
        return MailboxLink(self.psram_path, os.dup(self._bells[0]), os.dup(self._bells[1]))

    @property
    def link_spec(self) -> str:
        """`serial:fd:N` on a duplicate of the connected socket (the link owns and closes it)."""
        assert self._sock is not None
        return f"serial:fd:{os.dup(self._sock.fileno())}"

    def instruction_counts(self) -> np.ndarray:
        """Instructions of every control step so far (the markers' own cost subtracted), in step order."""
        if self.counts_path is None or not self.counts_path.exists():
            return np.zeros(0, dtype=np.int64)
        raw = array("I")
        data = self.counts_path.read_bytes()
        raw.frombytes(data[: len(data) // 4 * 4])
        if sys.byteorder != "little":  # pragma: no cover
            raw.byteswap()
        counts = np.asarray(raw, dtype=np.int64)
        if len(counts) == 0:
            return counts
        # the first record is the empty begin/end pair at boot: the markers' own cost
        return np.asarray(counts[1:] - counts[0], dtype=np.int64)

    def metrics(self) -> dict[str, Any]:
        """exec_instructions {median, p99, max} and the estimate exec_time_us over the steps from `skip_steps`
        (the metrics window), plus the clock and cycle model; {} without counts."""
        counts = self.instruction_counts()
        window = counts[self.skip_steps:] if len(counts) > self.skip_steps else counts
        out: dict[str, Any] = {"mcu_clock_hz": self.mcu_clock_hz, "exec_time_model": CYCLE_MODEL}
        if len(window) == 0:
            out["exec_instructions"] = None
            return out
        out["exec_instructions"] = stats(window)
        out["exec_instructions"]["steps"] = len(window)
        us = window * (CPI / self.mcu_clock_hz * 1e6)
        out["exec_time_us"] = stats(us)
        return out

    def close(self) -> None:
        """Stop QEMU (SIGTERM, then SIGKILL) and remove its files; idempotent."""
        if self._sock is not None:
            with contextlib.suppress(OSError):
                self._sock.close()
            self._sock = None
        if self._bells is not None:  # the firmware, blocked on its doorbell, reads end-of-file and moves on
            for fd in self._bells:
                with contextlib.suppress(OSError):
                    os.close(fd)
            self._bells = None
        proc = self.process
        if proc is not None and proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        self.process = None
        self._progress = None
        if self._progress_map is not None:
            with contextlib.suppress(BufferError, ValueError):
                self._progress_map.close()
            self._progress_map = None
        with contextlib.suppress(OSError, ValueError):
            self._stderr.close()
        shutil.rmtree(self._dir, ignore_errors=True)

    def __del__(self) -> None:  # a forgotten target still stops
        with contextlib.suppress(Exception):
            if self.process is not None and self.process.poll() is None:
                self.process.kill()


class MailboxLink:
    """The host's end of the PSRAM mailbox (implements the Link protocol): `send` waits for the reply to the
    previous request (collecting its frames), writes the frames and their length, then the sequence word in one
    aligned 32-bit store, and rings the target's doorbell (one byte into the host-to-target FIFO); `poll`
    returns the reply's frames once the target has echoed the sequence word. While a reply is outstanding
    `poll` waits for it, asleep on the target's doorbell (the target-to-host FIFO) for up to `WAIT_SLICE_MS`.
    Neither end spins: two spinners on a busy machine stall each other for scheduler time slices
    (milliseconds). The link owns (and closes) the two doorbell descriptors."""

    def __init__(self, psram: Path, bell_out: int, bell_in: int) -> None:
        self.stats = LinkStats()
        self.fd = True
        self._bell_out, self._bell_in = bell_out, bell_in
        self._file = open(psram, "r+b")  # noqa: SIM115 (closed in close())
        self._map = mmap.mmap(self._file.fileno(), MBOX_T2H_BUF + MBOX_BUF_SIZE)
        self._h2t_seq = ctypes.c_uint32.from_buffer(self._map, MBOX_H2T_SEQ)
        self._h2t_len = ctypes.c_uint32.from_buffer(self._map, MBOX_H2T_LEN)
        self._t2h_seq = ctypes.c_uint32.from_buffer(self._map, MBOX_T2H_SEQ)
        self._t2h_len = ctypes.c_uint32.from_buffer(self._map, MBOX_T2H_LEN)
        self._poller = select.poll()
        self._poller.register(bell_in, select.POLLIN)
        self._seq = self._h2t_seq.value
        self._pending = False
        self._rx: deque[Frame] = deque()
        self._closed = False

    def _collect(self) -> bool:
        """Take the reply to the pending request if it is complete; True when nothing is pending."""
        if not self._pending:
            return True
        if self._t2h_seq.value != self._seq:
            return False
        n = min(self._t2h_len.value, MBOX_BUF_SIZE)
        buf = self._map[MBOX_T2H_BUF:MBOX_T2H_BUF + n]
        pos = 0
        while pos + 6 <= n:
            ident = int.from_bytes(buf[pos:pos + 4], "little")
            fd, length = buf[pos + 4], buf[pos + 5]
            self._rx.append(Frame(ident, bytes(buf[pos + 6:pos + 6 + length]), bool(fd)))
            self.stats.frames_rx += 1
            pos += 6 + length
        self._pending = False
        return True

    @property
    def pending(self) -> bool:
        """A request awaits its reply."""
        return self._pending

    def _wait(self) -> bool:
        """True once nothing is pending (the reply collected at once or after the target's doorbell); False
        after a quiet slice of WAIT_SLICE_MS (the caller checks its deadline)."""
        if self._collect():
            return True
        # the target rings after it echoes the sequence word. A bell read here may be an earlier reply's
        # (replies found at once leave theirs unread): the look after it decides, a miss waits again.
        if self._poller.poll(WAIT_SLICE_MS):
            with contextlib.suppress(BlockingIOError, InterruptedError):
                os.read(self._bell_in, 65536)
        return self._collect()

    def send(self, frames: Sequence[Frame]) -> None:
        """One request carrying `frames`."""
        if not self._collect():
            deadline = time.perf_counter() + MAILBOX_TIMEOUT_S
            while not self._wait():
                if time.perf_counter() > deadline:
                    self.stats.send_errors += 1
                    raise LinkError(f"mailbox: the target did not answer request {self._seq} within "
                                    f"{MAILBOX_TIMEOUT_S:g} s")
        body = b"".join(f.arbitration_id.to_bytes(4, "little") + bytes((1 if f.is_fd else 0, len(f.data))) + f.data
                        for f in frames)
        if len(body) > MBOX_BUF_SIZE:
            self.stats.send_errors += 1
            raise LinkError(f"mailbox: {len(body)} bytes in one request (at most {MBOX_BUF_SIZE})")
        self._map[MBOX_H2T_BUF:MBOX_H2T_BUF + len(body)] = body
        self._h2t_len.value = len(body)
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        self._pending = True
        self._h2t_seq.value = self._seq  # last, one aligned 32-bit store
        try:
            os.write(self._bell_out, b"\x00")  # the target's doorbell
        except OSError as exc:  # EAGAIN: 64 KiB of unread bells, the target no longer reads them
            self.stats.send_errors += 1
            raise LinkError(f"mailbox: doorbell: {exc}") from None
        self.stats.frames_tx += len(frames)

    def poll(self) -> Frame | None:
        """The next reply frame; None when nothing is outstanding, or after a quiet wait slice."""
        rx = self._rx
        if not rx:
            if not self._pending:
                return None
            self._wait()
            if not rx:
                return None
        return rx.popleft()

    def recv(self, timeout_s: float) -> Frame | None:
        """Wait up to `timeout_s` seconds."""
        end = time.perf_counter() + timeout_s
        while True:
            frame = self.poll()
            if frame is not None or time.perf_counter() >= end:
                return frame

    def close(self) -> None:
        """Unmap the mailbox and close the doorbells (idempotent)."""
        if self._closed:
            return
        self._closed = True
        del self._h2t_seq, self._h2t_len, self._t2h_seq, self._t2h_len
        with contextlib.suppress(BufferError, ValueError):
            self._map.close()
        self._file.close()
        for fd in (self._bell_out, self._bell_in):
            with contextlib.suppress(OSError):
                os.close(fd)
