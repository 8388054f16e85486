"""Software in the loop: a firmware of the HIL target core built for the host (`hil fw build --board host`)
as a shared library, loaded here and served by a `hil target --native --sil PATH` process (the default: the
runner's process survives the firmware's crashes) or in the runner's process behind any link like the Python
virtual target (`--sil-in-process`).

The library exports the core (firmware_stub/target/hil_target_core.h): frames in (`hil_core_rx`), frames out
(`hil_core_tx`). Each `SilFirmware` loads a private copy of the library, so two instances (two runs in one
process) never share the firmware's globals.
"""

from __future__ import annotations

import ctypes
import shutil
import tempfile
from pathlib import Path
from typing import NamedTuple

from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import Link
from pmsm_hil.sim_target.firmware import FirmwareError
from pmsm_hil.sim_target.target import serve_pending

SIL_ABI_VERSION = 1
MAX_PAYLOAD = 64


class SilError(FirmwareError):
    """The library is missing, not a HIL target core library, or of another ABI version."""


class _Frame(ctypes.Structure):
    _fields_ = [("id", ctypes.c_uint32), ("len", ctypes.c_uint8), ("fd", ctypes.c_uint8),
                ("data", ctypes.c_uint8 * MAX_PAYLOAD)]


class _Cmd(ctypes.Structure):
    _fields_ = [("n_states", ctypes.c_uint8), ("states", ctypes.c_uint8 * 3), ("durations_ns", ctypes.c_uint32 * 3),
                ("mirror", ctypes.c_uint8), ("vector_id", ctypes.c_uint8), ("candidates", ctypes.c_uint8),
                ("status", ctypes.c_uint8), ("torque_ref", ctypes.c_float), ("id_ref", ctypes.c_float),
                ("iq_ref", ctypes.c_float), ("n_duties", ctypes.c_uint8), ("duty", ctypes.c_float * 6)]


COUNTER_NAMES = ("frames_rx", "measurements", "commands", "config_writes", "config_rejected", "faults",
                 "unknown_id", "bad_length", "tx_overflow", "steps")


class _Counters(ctypes.Structure):
    _fields_ = [(name, ctypes.c_uint32) for name in COUNTER_NAMES]


class SilStep(NamedTuple):
    """What the runner's in-process hook reads after each Command (no stage split: (0, 0, 0))."""

    split_ns: tuple[int, int, int]
    torque_ref: float
    exec_time_ns: int
    full_miss: int = 255


class SilFirmware:
    """One loaded copy of a SIL library."""

    def __init__(self, library: str | Path, *, init: bool = True) -> None:
        path = Path(library)
        if not path.is_file():
            raise SilError(f"SIL library {path} not found (build one with `hil fw build --board host`)")
        with tempfile.TemporaryDirectory(prefix="hil-sil-") as tmp:  # a private copy: private globals
            private = Path(tmp) / path.name
            shutil.copyfile(path, private)
            try:
                lib = ctypes.CDLL(str(private))
            except OSError as exc:
                raise SilError(f"SIL library {path}: cannot load ({exc})") from None
        try:
            version = lib.hil_sil_abi_version()
            self._rx = lib.hil_core_rx
            self._tx = lib.hil_core_tx
            lib.hil_core_counters.restype = ctypes.POINTER(_Counters)
            lib.hil_core_last_cmd.restype = ctypes.POINTER(_Cmd)
            lib.hil_core_last_exec_ns.restype = ctypes.c_uint32
        except AttributeError as exc:
            raise SilError(f"SIL library {path}: not a HIL target core library ({exc})") from None
        if version != SIL_ABI_VERSION:
            raise SilError(f"SIL library {path}: ABI version {version}, this host speaks {SIL_ABI_VERSION} "
                           "(rebuild it)")
        self._rx.argtypes = [ctypes.c_uint32, ctypes.c_char_p, ctypes.c_uint8, ctypes.c_uint8]
        self._rx.restype = None
        self._tx.argtypes = [ctypes.POINTER(_Frame)]
        self._tx.restype = ctypes.c_int
        self._lib = lib
        self._out = _Frame()
        self._out_ref = ctypes.byref(self._out)
        self._counters = lib.hil_core_counters().contents
        self._last = lib.hil_core_last_cmd().contents
        self.path = path
        if init:
            lib.hil_core_init()

    def init(self) -> None:
        """Initialise the core and the firmware (`hil_app_init`): for a copy loaded with `init=False`."""
        self._lib.hil_core_init()

    def feed(self, frame: Frame) -> list[Frame]:
        """One received frame; the frames the core answers with."""
        data = frame.data
        self._rx(frame.arbitration_id, data, len(data), 1 if frame.is_fd else 0)
        replies: list[Frame] = []
        out = self._out
        while self._tx(self._out_ref):
            replies.append(Frame(out.id, bytes(out.data[:out.len]), bool(out.fd)))
        return replies

    def entry_points(self) -> tuple[int, int]:
        """Addresses of this copy's `hil_core_rx` and `hil_core_tx` (for a C serve loop in this process)."""
        rx = ctypes.cast(self._rx, ctypes.c_void_p).value
        tx = ctypes.cast(self._tx, ctypes.c_void_p).value
        assert rx is not None and tx is not None
        return rx, tx

    def debug_sources(self) -> tuple[int, int]:
        """Addresses of this copy's step counter (u32) and last torque reference (float32, hil_app_cmd_t's debug
        output): what the C serve loop copies after each step for the host (`nt_serve_core_debug`)."""
        return (ctypes.addressof(self._counters) + _Counters.steps.offset,
                ctypes.addressof(self._last) + _Cmd.torque_ref.offset)

    def counters(self) -> dict[str, int]:
        """The core's counters (hil_core_counters_t)."""
        return {name: int(getattr(self._counters, name)) for name in COUNTER_NAMES}

    @property
    def steps(self) -> int:
        """Control steps run so far."""
        return int(self._counters.steps)

    def last_step(self) -> SilStep:
        """Debug outputs of the last control step and its host execution time."""
        return SilStep((0, 0, 0), float(self._last.torque_ref), int(self._lib.hil_core_last_exec_ns()))


class SilTarget:
    """A SIL firmware behind a link; `service()` processes every pending frame (non-blocking), like
    `SimTarget`."""

    def __init__(self, link: Link, library: str | Path) -> None:
        self.link = link
        self.firmware = SilFirmware(library)

    def service(self) -> int:
        """Process all frames waiting on the link; returns the number of frames handled."""
        return serve_pending(self.link.poll, self._on_frame)

    def _on_frame(self, frame: Frame) -> None:
        replies = self.firmware.feed(frame)
        if replies:
            self.link.send(replies)

    def last_result(self) -> SilStep | None:
        """The last control step (None before the first)."""
        return self.firmware.last_step() if self.firmware.steps else None
