"""The debug outputs of a SIL target in its own process: after each step the target's C serve loop
copies the step's torque reference (the library's hil_app_cmd_t debug output, which no frame carries) into memory
it shares with the host (a memfd passed to `hil target --sil-debug-fd`), before the step's Command is sent; the
host's C loop reads it for the Command it received (loop.h `nl_sil_debug_t`), so an isolated SIL run logs
`torque_ref` as the in-process one does."""

from __future__ import annotations

import mmap
import os
from typing import Any

#: bytes of the shared memory (one page; nl_sil_debug_t uses 8)
SIL_DEBUG_BYTES = 4096


class SilDebugSlot:
    """The host's end: a memfd the target process inherits and the host maps."""

    def __init__(self) -> None:
        self.fd = os.memfd_create("hil-sil-debug", os.MFD_CLOEXEC)
        try:
            os.ftruncate(self.fd, SIL_DEBUG_BYTES)
            self._map: mmap.mmap | None = mmap.mmap(self.fd, SIL_DEBUG_BYTES)
        except BaseException:
            os.close(self.fd)
            raise
        self._ptr: Any = None
        self._ffi: Any = None

    def pointer(self, ffi: Any) -> Any:
        """An `nl_sil_debug_t *` on the memory (for nl_target_link_cfg_t.sil_debug; valid until `close`)."""
        if self._ptr is None:
            assert self._map is not None
            self._ffi, self._ptr = ffi, ffi.from_buffer("nl_sil_debug_t *", self._map)
        return self._ptr

    def close_fd(self) -> None:
        """Close the descriptor (once the target process has it); the mapping stays."""
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    def close(self) -> None:
        """Unmap and close (idempotent; after the C loop no longer reads it)."""
        self.close_fd()
        if self._ptr is not None:
            self._ffi.release(self._ptr)
            self._ptr = None
        if self._map is not None:
            self._map.close()
            self._map = None
