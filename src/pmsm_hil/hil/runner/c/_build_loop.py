"""cffi (API mode) builder of the native period loop: extension `pmsm_hil.hil._loop_native`.

The cdef is taken from the C headers only (src/pmsm_hil/hil/cdef_extract.py): every struct, typedef, prototype and
integer constant from the header that declares it (this folder, links/, hil/kernels, firmware_stub/target), structs cut
down to the fields Python reads where the rest is private (`partial`), the extension's own glue from loop_py.h; cffi
checks the layouts against the real headers when it compiles. tests/plant/test_cdef_extract.py fails on a restated one.

Two sets of flags: the firmware side (reference firmware, HIL target core, generated codec) is compiled with
the firmware's strict flags (`-fsingle-precision-constant`, as every other build of it) into objects linked
in; the loop and the plant (double precision) with the plant's flags plus `-Werror`, no FMA contraction and
no sin/cos fusion, so every value equals the Python loop's bit for bit.
"""

from __future__ import annotations

import runpy
import tempfile
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from cffi import FFI

#: the loop's C (this folder), its links (links/), the plant kernels (src/pmsm_hil/hil/kernels) and the repository
_HERE = Path(__file__).resolve().parent
_LINKS = _HERE / "links"
_HIL = _HERE.parents[1]
_KERNELS = _HIL / "kernels"
_ROOT = _HIL.parents[2]
_FW = _ROOT / "firmware_stub"
_FW_INCLUDES = [_FW / "include", _FW / "generated", _FW / "target"]

#: the firmware's strict flags (firmware_stub/target/hil_target.cmake HIL_STRICT_FLAGS)
FIRMWARE_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-fsingle-precision-constant",
                  "-O2", "-fPIC", "-DHIL_APP_REFERENCE_PROFILED"]
LOOP_FLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-ffp-contract=off",
              "-fno-builtin-sin", "-fno-builtin-cos", "-pthread"]
LOOP_SOURCES = ("loop.c", "loop_frames.c", "loop_rt.c", "target_serve.c", "loop_board.c", "loop_fmu.c",
                "loop_fmu_box.c", "pwm_duty.c", "loop_stall.c")
#: the C links (links/): the link interface, the in-process link to the C target core, the link to the virtual
#: STM32G4 board, the UDP, serial and SocketCAN links, the UDP floor
LINK_SOURCES = ("nl_link.c", "link_core.c", "link_board.c", "loop_udp.c", "loop_serial.c", "loop_socketcan.c",
                "link_floor.c")


#: src/pmsm_hil/hil/cdef_extract.py by path (this script runs at build time, before the package is importable)
_X = SimpleNamespace(**runpy.run_path(str(_HIL / "cdef_extract.py")))
#: the FMI 2.0 / 3.0 headers loop_fmu.c includes: the installed fmpy's (a build requirement, pyproject.toml), found
#: by src/pmsm_hil/hil/load_fmu/headers.py (by path, as above); a clear error when fmpy is missing
FMI_INCLUDE = runpy.run_path(str(_HIL / "load_fmu" / "headers.py"))["fmi_include_dir"]()
_TARGET = _FW / "target"
#: every integer macro of the headers the loop's cdef reads: an array size in one header given by a macro of
#: another (nl_gap_probe_t's NL_LATE_BINS of loop.h, nl_serial_t's NL_SERIAL_MAX_ENCODED of four headers) resolves
_MACROS = _X.constants(*sorted(_HERE.glob("*.h")), *sorted(_LINKS.glob("*.h")), *sorted(_KERNELS.glob("*.h")),
                       *(h for d in _FW_INCLUDES for h in sorted(d.glob("*.h"))))


def _decl(header: Path, names: list[str], **options: Any) -> str:
    """The named declarations of `header` (cdef_extract.declarations, every macro of _MACROS known)."""
    text: str = _X.declarations(header, names, macros=_MACROS, **options)
    return text


#: loop.h and machine_kernel.h as cffi reads them: their integer constants, the finding, configuration and result
#: structs and the handle's functions - taken from the headers, never restated
LOOP_H_CDEF = (_X.cffi_constants(_HERE / "loop_fmu.h", "NL_FMU_")
               + _decl(_HERE / "loop_fmu.h", ["nl_fmu_t", "nl_fmu_open", "nl_fmu_enter_init", "nl_fmu_set",
                                               "nl_fmu_exit_init", "nl_fmu_period", "nl_fmu_close", "nl_fmu_box_size",
                                               "nl_fmu_box_attach", "nl_fmu_box_ready",
                                               "nl_fmu_stop", "nl_fmu_serve"])
               + _X.cffi_constants(_HERE / "loop.h", "NL_")
               + _X.cffi_constants(_KERNELS / "machine_kernel.h", "MK_")
               + _decl(_KERNELS / "machine_kernel.h", ["mk_kernel_t"], opaque=["mk_kernel_t"])
               # a ring slot: Python reads its counts and trace (the records through the nl_slot_* views)
               + _decl(_HERE / "loop.h", ["nl_finding_t", "nl_sil_debug_t", "nl_machine_cfg_t", "nl_operation_cfg_t",
                                          "nl_codec_cfg_t", "nl_target_link_cfg_t", "nl_timing_cfg_t",
                                          "nl_sensors_cfg_t", "nl_outputs_cfg_t", "nl_config_t", "nl_slot_t",
                                          "nl_result_t", "nl_handle_t", "nl_handle_size", "nl_init", "nl_destroy",
                                          "nl_config", "nl_slot", "nl_result", "nl_run", "nl_wait_full", "nl_release",
                                          "nl_stop"],
                       partial={"nl_slot_t": ["trace", "trace_rows_cap", "n_periods", "n_frames", "n_findings",
                                              "n_trace_rows"]}))

#: the frames, the links and the target's serve loop, each from its own header; partial structs: the link is
#: opaque (Python only hands it over), the authentication and serial framer states show what Python reads
LINKS_CDEF = (_decl(_TARGET / "hil_target_core.h", ["hil_core_frame_t", "hil_core_counters_t", "hil_core_init",
                                                    "hil_core_rx", "hil_core_tx", "hil_core_counters"])
              + _decl(_HERE / "loop_frames.h", ["nl_encode_meas"])
              + _decl(_LINKS / "nl_link.h", ["nl_link_t", "nl_link_stats_t"], partial={"nl_link_t": []})
              + _decl(_TARGET / "hil_auth.h", ["hil_auth_t", "hil_auth_init", "hil_auth_set_context", "hil_auth_seal",
                                               "hil_auth_open", "hil_hmac_sha256"],
                      partial={"hil_auth_t": ["on", "tx_fresh", "rx_fresh", "tx_dir", "rx_dir", "ctx_n", "ctx"]})
              + _X.cffi_constants(_LINKS / "nl_link.h", "NL_SPIN_")
              + _decl(_LINKS / "nl_link.h", ["nl_spin_t", "nl_wait_readable"])
              + _decl(_HERE / "loop_rt.h", ["nl_gap_probe_t", "nl_gap_probe", "nl_now_ns"])
              + _decl(_HERE / "loop_stall.h", ["nl_proc_sample_t", "nl_own_time_t", "nl_own_time_start",
                                                "nl_own_time_step"])
              + _decl(_LINKS / "link_floor.h", ["nl_udp_floor_t", "nl_udp_floor", "nl_udp_paced_floor_t",
                                                 "nl_udp_paced_floor"])
              + _decl(_LINKS / "link_core.h", ["nl_core_link_t", "nl_core_link"])
              + _X.cffi_constants(_LINKS / "link_board.h", "NL_BOARD_")
              + _decl(_LINKS / "link_board.h",
                      ["nl_board_meas_t", "nl_board_cmd_t", "nl_board_inputs_fn", "nl_board_outputs_fn",
                       "nl_board_fast_fn", "nl_board_link_t", "nl_board_recv"],
                      partial={"nl_board_link_t": ["scale_i", "scale_theta", "scale_omega", "scale_vdc", "inputs",
                                                   "inputs_user", "outputs", "outputs_user", "fast", "fast_user",
                                                   "py_pending", "stats"]})
              + _decl(_LINKS / "loop_udp.h", ["nl_udp_t", "nl_udp_link"])
              + _decl(_TARGET / "hil_serial.h", ["hil_serial_t"], partial={"hil_serial_t": ["tx_seq"]})
              + _decl(_LINKS / "loop_serial.h", ["nl_serial_t", "nl_serial_link", "nl_serial_send", "nl_serial_recv"])
              + _decl(_LINKS / "loop_socketcan.h", ["nl_socketcan_t", "nl_socketcan_link", "nl_socketcan_send",
                                                   "nl_socketcan_recv"])
              + _X.cffi_constants(_HERE / "target_serve.h", "NT_END_")
              + _decl(_HERE / "target_serve.h", ["nt_serve", "nt_core_rx_fn", "nt_core_tx_fn", "nt_serve_core",
                                                 "nt_serve_core_debug"]))

#: the extension's own glue (loop_py.h): slot views, and the callback link whose send / recv / diag / period
#: src/pmsm_hil/hil/runner/callback_link.py defines in Python
PY_CDEF = _decl(_HERE / "loop_py.h", ["nl_sizeof_period", "nl_sizeof_frame", "nl_slot_periods", "nl_slot_frames",
                                      "nl_slot_lateness", "nl_slot_findings", "nl_slot_noise", "nl_py_send",
                                      "nl_py_recv", "nl_py_diag", "nl_py_period", "nl_py_link", "nl_py_board_period",
                                      "nl_py_board_link"],
                extern_python=["nl_py_send", "nl_py_recv", "nl_py_diag", "nl_py_period", "nl_py_board_period"])

CDEF = LOOP_H_CDEF + _decl(_HERE / "pwm_duty.h", ["pwm_duty_sequence"]) + LINKS_CDEF + PY_CDEF

PREAMBLE = """
#include "loop.h"
#include "loop_fmu.h"
#include "pwm_duty.h"
#include "machine_kernel.h"
#include "loop_frames.h"
#include "loop_rt.h"
#include "loop_stall.h"
#include "hil_target_core.h"
#include "link_core.h"
#include "link_board.h"
#include "loop_udp.h"
#include "loop_serial.h"
#include "loop_socketcan.h"
#include "target_serve.h"
#include "link_floor.h"
#include "loop_py.h"
"""


def _rel(path: Path) -> str:
    """Path relative to the working directory when possible (setuptools wants that)."""
    return str(path.relative_to(Path.cwd())) if path.is_relative_to(Path.cwd()) else str(path)


def _firmware_objects() -> list[str]:
    """Compile the firmware side with its own flags; the object files to link."""
    from setuptools._distutils.ccompiler import new_compiler
    from setuptools._distutils.sysconfig import customize_compiler

    cc = new_compiler()
    customize_compiler(cc)
    sources = [*sorted((_FW / "src").glob("*.c")), _FW / "target" / "hil_target_core.c",
               _FW / "target" / "hil_app_reference.c", _FW / "target" / "hil_serial.c", _FW / "target" / "hil_auth.c",
               _FW / "generated" / "hil_protocol.c"]
    out = tempfile.mkdtemp(prefix="hil-loop-fw-")
    objects: list[str] = cc.compile([str(s) for s in sources], output_dir=out,
                                    include_dirs=[str(p) for p in _FW_INCLUDES], extra_postargs=FIRMWARE_FLAGS)
    return objects


ffibuilder = FFI()
ffibuilder.cdef(CDEF)
ffibuilder.set_source(
    "pmsm_hil.hil._loop_native",
    PREAMBLE,
    sources=[_rel(_HERE / name) for name in LOOP_SOURCES] + [_rel(_LINKS / name) for name in LINK_SOURCES],
    include_dirs=[_rel(_HERE), _rel(_LINKS), _rel(_KERNELS), *(_rel(p) for p in _FW_INCLUDES), str(FMI_INCLUDE)],
    extra_compile_args=LOOP_FLAGS,
    extra_objects=_firmware_objects(),
    libraries=["m", "pthread", "dl"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
