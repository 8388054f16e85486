"""The cffi declarations come from the C headers (src/pmsm_hil/hil/cdef_extract.py): named typedefs and prototypes,
macros in array sizes replaced (integer expressions, across headers), integer constants listed, structs cut down or
opaque, glue functions from their definitions; a name the header lacks is an error naming it; no build script restates a
header."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from cffi import FFI

from pmsm_hil.hil.cdef_extract import cffi_constants, constants, declarations, declared_names, evaluate

HEADER = """/* a header */
#ifndef X_H
#define X_H
#include <stdint.h>
#define X_N 4            /* legs */
#define X_E_BAD (-7)
#define X_PACKED __attribute__((packed))
typedef int (*x_fn)(void *ctx, const int32_t *v); /* a callback */
typedef struct NL_PACKED {
    double a[X_N];        // per leg
    int32_t b;
} x_state_t;
int x_step(x_state_t *s, x_fn f,
           int32_t n);
static inline int x_private(void) { return 1; }
#endif
"""


def test_named_declarations_as_cffi_reads_them(tmp_path: Path) -> None:
    h = tmp_path / "x.h"
    h.write_text(HEADER, encoding="utf-8")
    text = declarations(h, ["x_fn", "x_state_t", "x_step"])
    assert "double a[4];" in text and "NL_PACKED" not in text and "/*" not in text and "//" not in text
    assert constants(h) == {"X_N": 4, "X_E_BAD": -7}
    assert cffi_constants(h, "X_E") == "#define X_E_BAD ...\n"
    ffi = FFI()
    ffi.cdef(text)  # parses
    assert ffi.sizeof("x_state_t") == 4 * 8 + 8  # 4 doubles and an int32 (padded to 8)
    with pytest.raises(KeyError, match=r"x\.h: no declaration of x_missing"):
        declarations(h, ["x_step", "x_missing"])


def test_the_bundled_headers_give_the_structs_the_plant_uses() -> None:
    from pmsm_hil.hil._plant_native import ffi

    native = Path(__file__).resolve().parents[2] / "src" / "pmsm_hil" / "hil" / "kernels"
    text = declarations(native / "plant.h", ["pl_params_t", "pl_state_t"])
    assert "ge_legs_t legs;" in text
    assert "int32_t dead_level[6];" in declarations(native / "gate_edges.h", ["ge_legs_t"])
    assert ffi.sizeof("pl_state_t") > 0 and ffi.sizeof("mk_sample_t") == 13 * 8


GLUE = """/* a glue header */
#ifndef G_H
#define G_H
#include "x.h"
#ifdef __cplusplus
extern "C" {
#endif
#define G_LEGS (X_N + 2)        /* a size from another header */
#define G_BYTES (G_LEGS * 8u / 3u - (1 << 2))
#define G_BIT(p) (1u << (p))
#define G_MASK (G_BIT(1) | 4u)
typedef struct g_link {
    int (*send)(void *ctx);
    void *ctx;
} g_link_t;
typedef struct g_state {
    int64_t a, b[G_LEGS], c;   /* two kept, one not */
    g_link_t link;
    union { int32_t i; float f; } u;
    uint8_t tail[X_N];
} g_state_t;
static int g_py_send(void *ctx);
static size_t g_size(void) { return sizeof(g_state_t); }
typedef struct { int32_t after_a_definition; } g_after_t;
#ifdef __cplusplus
}
#endif
#endif
"""


def _glue(tmp_path: Path) -> tuple[Path, Path]:
    x, g = tmp_path / "x.h", tmp_path / "g.h"
    x.write_text(HEADER, encoding="utf-8")
    g.write_text(GLUE, encoding="utf-8")
    return x, g


def test_macros_of_several_headers_resolve_as_c_integer_expressions(tmp_path: Path) -> None:
    x, g = _glue(tmp_path)
    values = constants(x, g)
    assert values["G_LEGS"] == 6 and values["G_BYTES"] == 6 * 8 // 3 - 4  # truncating division, shifts
    assert "G_LEGS" not in constants(g)  # X_N is not known from g.h alone
    assert "G_BIT" not in values and "G_MASK" not in values and "X_PACKED" not in values  # not integer macros
    assert evaluate("-7 / 2", {}) == -3 and evaluate("-7 % 2", {}) == -1 and evaluate("010", {}) == 8  # C, not Python
    assert evaluate("(uint64_t)1u", {}) is None and evaluate("1 +", {}) is None and evaluate("1 / 0", {}) is None
    with pytest.raises(KeyError, match=r"array size 'G_LEGS'"):
        declarations(g, ["g_state_t"])  # the size needs x.h: an error naming it, never a guess
    y = tmp_path / "y.h"
    y.write_text("#define X_N 5\n", encoding="utf-8")
    with pytest.raises(ValueError, match="X_N is defined as both 4 and 5"):
        constants(x, y)
    assert cffi_constants(g, names=["G_BYTES"], macros=constants(x)) == "#define G_BYTES ...\n"
    with pytest.raises(KeyError, match="no integer macro G_NONE"):
        cffi_constants(g, names=["G_NONE"])


def test_partial_opaque_python_and_glue_declarations(tmp_path: Path) -> None:
    x, g = _glue(tmp_path)
    text = declarations(g, ["g_link_t", "g_state_t", "g_py_send", "g_size", "g_after_t"], macros=constants(x, g),
                        partial={"g_link_t": [], "g_state_t": ["a", "c", "u", "tail"]}, extern_python=["g_py_send"])
    assert "typedef struct g_link {\n    ...;\n} g_link_t;" in text  # no field typed twice: none at all
    assert "    int64_t a;\n    int64_t c;\n" in text and " b[" not in text and "link;" not in text
    assert "union { int32_t i; float f; } u;" in text and "uint8_t tail[4];" in text and text.count("...;") == 2
    assert 'extern "Python" int g_py_send(void *ctx);' in text
    assert "size_t g_size(void);" in text and "static" not in text and "return" not in text  # a definition's prototype
    assert "after_a_definition" in text and 'extern "C"' not in text
    assert declarations(g, ["g_state_t"], macros=constants(x, g), opaque=["g_state_t"]) == \
        "typedef struct g_state g_state_t;\n"
    ffi = FFI()
    ffi.cdef(text)  # cffi reads all of it
    with pytest.raises(KeyError, match="g_state_t: no field d"):
        declarations(g, ["g_state_t"], macros=constants(x, g), partial={"g_state_t": ["a", "d"]})
    with pytest.raises(KeyError, match="g_link_t not among the names"):
        declarations(g, ["g_state_t"], macros=constants(x, g), partial={"g_link_t": []})
    with pytest.raises(KeyError, match="needs the tag"):
        declarations(x, ["x_state_t"], opaque=["x_state_t"])


def test_a_partial_struct_keeps_the_headers_layout_in_the_built_extensions() -> None:
    """cffi checked the cut-down structs against the real headers when it compiled: the fields Python reads sit
    where C has them, the sizes are C's (a size from macros of four headers: nl_serial_t.pkt)."""
    from pmsm_hil.hil._loop_native import ffi
    from pmsm_hil.sim_target._firmware import ffi as fw_ffi

    headers = [*LOOP_C.rglob("*.h"), *(h for d in FIRMWARE_HEADER_DIRS for h in d.glob("*.h"))]
    values = constants(*headers)
    assert values["NL_SERIAL_MAX_ENCODED"] == values["HIL_SERIAL_MAX_ENCODED"] + values["HIL_AUTH_TRAILER"] == 80
    fields = dict(ffi.typeof("nl_serial_t").fields)
    assert fields["pkt"].type.length == values["NL_SERIAL_MAX_ENCODED"]
    assert [name for name, _ in ffi.typeof("nl_slot_t").fields] == ["trace", "trace_rows_cap", "n_periods",
                                                                    "n_frames", "n_findings", "n_trace_rows"]
    assert ffi.sizeof("nl_slot_t") > ffi.offsetof("nl_slot_t", "n_trace_rows")  # the records before, C's size
    # opaque to Python, its size C's: five pointers and the flags word (padded to a pointer)
    assert ffi.sizeof("nl_link_t") == 6 * ffi.sizeof("void *")
    assert fw_ffi.sizeof("hil_fw_state_t") > fw_ffi.offsetof("hil_fw_state_t", "reference") + 4


# --- no build script restates a header -------------------------------------------------------------------------
ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "pmsm_hil"
#: the C of the package: the loop and its links (src/pmsm_hil/hil/runner/c), the plant kernels
#: (src/pmsm_hil/hil/kernels)
LOOP_C, KERNELS = PACKAGE / "hil" / "runner" / "c", PACKAGE / "hil" / "kernels"
FIRMWARE_HEADER_DIRS = [ROOT / "firmware_stub" / d for d in ("include", "target", "generated")]
#: the scripts that hand cffi a cdef
BUILD_SCRIPTS = [LOOP_C / "_build_loop.py", KERNELS / "_build_plant.py", PACKAGE / "sim_target" / "_build_firmware.py",
                 PACKAGE / "hil" / "kernel_build.py", PACKAGE / "protocol" / "links" / "_build_wire.py"]


def header_names() -> set[str]:
    """Every typedef, function, struct tag and macro a header of the C side declares (the cffi glue headers too)."""
    headers = [*LOOP_C.rglob("*.h"), *KERNELS.glob("*.h"), *(h for d in FIRMWARE_HEADER_DIRS for h in d.glob("*.h")),
               *(PACKAGE / "sim_target").glob("*.h")]
    return set().union(*(declared_names(h.read_text(encoding="utf-8")) for h in headers))


def restated(source: str, known: set[str]) -> list[str]:
    """Names a Python source's string literals (docstrings aside) declare that a header declares already."""
    tree = ast.parse(source)
    docstrings = {id(node.value) for node in ast.walk(tree) if isinstance(node, ast.Expr)}
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            found |= declared_names(node.value) & known
    return sorted(found)


def test_the_rule_catches_a_restated_declaration() -> None:
    known = header_names()
    assert {"nl_udp_t", "nl_spin_t", "hil_fw_state_t", "hil_fw_step", "HIL_FW_OK", "NT_END_IDLE", "nt_core_rx_fn",
            "nl_py_link", "hil_fw_py_out_t", "hil_core_frame_t", "mk_kernel", "hil_app_step"} <= known
    old = '''CDEF = """
typedef struct {
    uint8_t tx_seq;
    ...;
} hil_serial_t;
#define NT_END_IDLE ...
typedef struct mk_kernel mk_kernel_t;
extern "Python" int nl_py_send(void *ctx, const hil_core_frame_t *f);
int32_t nt_serve(const nl_link_t *l, int64_t idle_ns, int32_t parent_pid);
typedef struct { int32_t mine; } my_own_t;
"""
'''
    assert restated(old, known) == ["NT_END_IDLE", "hil_serial_t", "mk_kernel", "mk_kernel_t", "nl_py_send",
                                    "nt_serve"]


@pytest.mark.parametrize("script", BUILD_SCRIPTS, ids=lambda p: p.name)
def test_no_build_script_restates_a_header(script: Path) -> None:
    """Every struct, typedef, prototype and constant cffi reads comes from its header through
    src/pmsm_hil/hil/cdef_extract.py; a declaration typed into a build script would drift from the header it copies."""
    assert restated(script.read_text(encoding="utf-8"), header_names()) == []
