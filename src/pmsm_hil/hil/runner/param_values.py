"""Checks of --param values as the target receives them: float32 on the wire (ConfigParam), and a controller
model that is not singular.

Rules (docs/protocol.md "Parameters"):
- every value must be a finite float32: |v| ≤ 3.4028235e38, and a nonzero value must not round to 0 in float32
  (|v| ≥ 1.4e-45, the smallest float32);
- the controller divides by its model's inductances, rotor resistance, pole pairs and control period: `ld`,
  `lq`, `lsigma`, `lm`, `rr`, `pole_pairs` and `ts` must be > 0 and a normal float32 (≥ 1.1754944e-38), so that
  their inverses are finite in float32; a value ≤ 0 or subnormal makes the model singular.
"""

from __future__ import annotations

from typing import Final

import numpy as np

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.protocol.ids import ParamId

FLOAT32_MAX: Final = float(np.finfo(np.float32).max)
FLOAT32_NORMAL_MIN: Final = float(np.finfo(np.float32).tiny)
#: --param values the reference controllers divide by (their model is singular unless each is > 0 and normal)
DIVISORS: Final = frozenset({ParamId.LD, ParamId.LQ, ParamId.LSIGMA, ParamId.LM, ParamId.RR, ParamId.POLE_PAIRS,
                             ParamId.TS})


def check_wire_value(name: str, value: float) -> None:
    """ParameterError naming `--param name` if `value` is not what the target receives as a float32."""
    if not abs(value) <= FLOAT32_MAX:
        raise ParameterError(f"--param {name}={value!r}: beyond the float32 range (±{FLOAT32_MAX:.8g}) the target "
                             "receives")
    if value != 0.0 and float(np.float32(value)) == 0.0:
        raise ParameterError(f"--param {name}={value!r}: rounds to 0 in float32 (the target receives 0); give 0 or a "
                             "value ≥ 1.4e-45 in magnitude")


def check_model_value(pid: ParamId, name: str, value: float) -> None:
    """ParameterError naming `--param name` if `value` makes the controller's model singular (see the module)."""
    if pid in DIVISORS and not value >= FLOAT32_NORMAL_MIN:
        raise ParameterError(f"--param {name}={value!r}: the controller's model would be singular: {name} must be "
                             f"> 0 and a normal float32 (≥ {FLOAT32_NORMAL_MIN:.8g}), the controller divides by it")


__all__ = ["DIVISORS", "FLOAT32_MAX", "FLOAT32_NORMAL_MIN", "check_model_value", "check_wire_value"]
