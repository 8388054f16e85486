"""cffi (API mode) builder of the wire extension `pmsm_hil.protocol.links._wire_native`: the hiludp and hilserial
links of the runner (src/pmsm_hil/hil/runner/c/links: loop_udp.c, loop_serial.c, nl_link.c) with the firmware's
framing and authentication (firmware_stub/target: hil_serial.c, hil_auth.c), built for the python-can buses of
this folder (wire_bus.py). The same C files are compiled into the period loop's extension: each wire is written
once, in C. The cdef is taken from the headers (src/pmsm_hil/hil/cdef_extract.py), never restated.
"""

from __future__ import annotations

import runpy
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from cffi import FFI

_HERE = Path(__file__).resolve().parent
_PKG = _HERE.parents[1]
_RUNNER_C = _PKG / "hil" / "runner" / "c"
_LINKS = _RUNNER_C / "links"
_ROOT = _PKG.parents[1]
_TARGET = _ROOT / "firmware_stub" / "target"
_INCLUDES = [_LINKS, _RUNNER_C, _PKG / "hil" / "kernels", _ROOT / "firmware_stub" / "include",
             _ROOT / "firmware_stub" / "generated", _TARGET]
FLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-pthread"]
SOURCES = [_LINKS / "nl_link.c", _LINKS / "loop_udp.c", _LINKS / "loop_serial.c", _RUNNER_C / "loop_rt.c",
           _TARGET / "hil_serial.c", _TARGET / "hil_auth.c"]

_X = SimpleNamespace(**runpy.run_path(str(_PKG / "hil" / "cdef_extract.py")))
_MACROS = _X.constants(*(h for d in _INCLUDES for h in sorted(d.glob("*.h"))))


def _decl(header: Path, names: list[str], **options: Any) -> str:
    text: str = _X.declarations(header, names, macros=_MACROS, **options)
    return text


CDEF = (_decl(_TARGET / "hil_target_core.h", ["hil_core_frame_t"])
        + _decl(_TARGET / "hil_auth.h", ["hil_auth_t", "hil_auth_init"],
                partial={"hil_auth_t": ["on", "tx_dir", "rx_dir"]})
        + _decl(_TARGET / "hil_serial.h", ["hil_serial_t"], partial={"hil_serial_t": ["tx_seq"]})
        + _X.cffi_constants(_LINKS / "nl_link.h", "NL_WIRE_")
        + _decl(_LINKS / "nl_link.h", ["nl_link_stats_t", "nl_spin_t", "nl_wire_frame_t"])
        + _decl(_LINKS / "loop_udp.h", ["nl_udp_t", "nl_udp_open", "nl_udp_local_port", "nl_udp_close",
                                         "nl_udp_propose", "nl_udp_send_wire", "nl_udp_recv_wire"])
        + _decl(_LINKS / "loop_serial.h", ["nl_serial_t", "nl_serial_attach", "nl_serial_close",
                                            "nl_serial_send_wire", "nl_serial_recv_wire"])
        + _decl(_RUNNER_C / "loop_rt.h", ["nl_now_ns"]))


def _rel(path: Path) -> str:
    """Path relative to the working directory when possible (setuptools wants that)."""
    return str(path.relative_to(Path.cwd())) if path.is_relative_to(Path.cwd()) else str(path)


ffibuilder = FFI()
ffibuilder.cdef(CDEF)
ffibuilder.set_source(
    "pmsm_hil.protocol.links._wire_native",
    '#include "loop_udp.h"\n#include "loop_serial.h"\n#include "loop_rt.h"\n',
    sources=[_rel(p) for p in SOURCES],
    include_dirs=[_rel(p) for p in _INCLUDES],
    extra_compile_args=FLAGS,
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
