"""The cffi declarations come from the C headers (hil/cdef_extract.py): named typedefs and prototypes, macros in
array sizes replaced, integer constants listed; a name the header lacks is an error naming it."""

from __future__ import annotations

from pathlib import Path

import pytest
from cffi import FFI
from pmsm_hil.hil.cdef_extract import cffi_constants, constants, declarations

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

    native = Path(__file__).resolve().parents[2] / "hil" / "native" / "kernels"
    text = declarations(native / "plant.h", ["pl_params_t", "pl_state_t"])
    assert "int32_t dead_level[3];" in text
    assert ffi.sizeof("pl_state_t") > 0 and ffi.sizeof("mk_sample_t") == 13 * 8
