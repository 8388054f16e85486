"""Python wrapper of the C reference firmware (cffi extension `pmsm_hil.sim_target._firmware`).

One `Firmware` owns one fixed-size C state record. Units are SI: currents A, angle rad (electrical),
speed rad/s (mechanical), voltage V, torque N·m, time ns. `CONTROLLERS` is the firmware's controller
table (name, id, phase count, implemented), read from C; names and ids are the DBC's (src/pmsm_hil/protocol/ids.py),
the phase count is a fact of this firmware that a foreign target need not share.
"""
from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from typing import Any, NamedTuple

from pmsm_hil.errors import HilError
from pmsm_hil.protocol.ids import CONTROLLER_NAMES, PARAM_NAMES, Mode

__all__ = [
    "CONTROLLERS",
    "CONTROLLER_IDS",
    "MODE_SPEED",
    "MODE_TORQUE",
    "PARAM_IDS",
    "ControllerInfo",
    "Firmware",
    "FirmwareBuildError",
    "FirmwareCommand",
    "FirmwareConfigError",
    "FirmwareError",
    "FirmwareInputError",
    "controller_by_name",
    "controller_phases",
]

# Shared numbering: the DBC value tables, through the generated src/pmsm_hil/protocol/ids.py.
PARAM_IDS: dict[str, int] = {name: int(p) for p, name in PARAM_NAMES.items()}
_PARAM_NAME_OF: dict[int, str] = {v: k for k, v in PARAM_IDS.items()}
CONTROLLER_IDS: dict[str, int] = {name: int(cid) for cid, name in CONTROLLER_NAMES.items()}
MODE_SPEED = int(Mode.SPEED)
MODE_TORQUE = int(Mode.TORQUE)


class FirmwareError(HilError):
    """Base of the firmware wrapper's errors."""


class FirmwareBuildError(FirmwareError):
    """The cffi extension is missing (not built)."""


class FirmwareConfigError(FirmwareError):
    """A parameter, controller or setpoint was rejected; the message names the field."""


class FirmwareInputError(FirmwareError):
    """A step input is malformed (wrong phase count, out-of-range seq or time)."""


class FirmwareCommand(NamedTuple):
    """Command k of the firmware, applied over [(k+1)Ts, (k+2)Ts).

    states: switching codes 4·Sa+2·Sb+Sc, one per used sub-interval; durations_ns: their lengths
    (sum = Ts); exec_time_ns: C-side step time (sum of split_ns = measurement, reference,
    prediction stages); torque_ref N·m, id_ref/iq_ref A: debug outputs of the outer loop;
    full_miss: diagnostics of the restricted-candidate controllers (fcs-mpc-1/2, dbcc-mpc), computed
    outside the timed stages: 1 if the full 19-vector DSVM set had a lower cost than the restricted
    set's choice this step, 0 if not, 255 not applicable. mirror: the plant applies states then
    states[-2::-1] with the same durations (2·(d0+…+d(n−2)) + d(n−1) = Ts; see `Command.mirror`).
    duties: the duty-cycle form (3 or 6 per-leg duties 0..1 of the centre-aligned PWM, float32 values; states
    and durations_ns empty then), () for the switching-state form.
    """

    seq: int
    states: tuple[int, ...]
    durations_ns: tuple[int, ...]
    vector_id: int
    candidates: int
    status: int
    exec_time_ns: int
    split_ns: tuple[int, int, int]
    torque_ref: float
    id_ref: float
    iq_ref: float
    full_miss: int = 255
    mirror: bool = False
    duties: tuple[float, ...] = ()


@cache
def _load() -> tuple[Any, Any]:
    try:
        from pmsm_hil.sim_target import _firmware  # type: ignore[attr-defined]
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise FirmwareBuildError(
            "firmware extension pmsm_hil.sim_target._firmware is not built; "
            "run `.venv/bin/pip install --no-build-isolation -e .`"
        ) from exc
    return _firmware.ffi, _firmware.lib


@dataclass(frozen=True, slots=True)
class ControllerInfo:
    """One entry of the firmware's controller table: DBC name and id, measured phases (3 or 6; 0 for
    `off`, which takes either), whether this build implements it and the parameter ids it reads."""

    name: str
    id: int
    phases: int
    implemented: bool
    params: frozenset[int] = frozenset()


def _read_table() -> tuple[ControllerInfo, ...]:
    """The C controller table, one entry per id below HIL_FW_CTRL_COUNT that has a table line."""
    ffi, lib = _load()
    out = []
    for cid in range(lib.HIL_FW_CTRL_COUNT):
        entry = lib.hil_fw_controller_get(cid)
        if entry != ffi.NULL:
            mask = int(entry.params)
            out.append(ControllerInfo(ffi.string(entry.name).decode("ascii"), int(entry.id), int(entry.phases),
                                      bool(lib.hil_fw_controller_implemented(cid)),
                                      frozenset(p for p in range(64) if mask >> p & 1)))
    return tuple(out)


#: The firmware's controller table, in id order.
CONTROLLERS: tuple[ControllerInfo, ...] = _read_table()


def controller_by_name(name: str) -> ControllerInfo:
    """The table entry called `name`; FirmwareConfigError listing the names if there is none."""
    for info in CONTROLLERS:
        if info.name == name:
            return info
    raise FirmwareConfigError(f"controller {name!r}: unknown to the firmware (known: "
                              f"{', '.join(c.name for c in CONTROLLERS)})")


def controller_phases(controller_id: int) -> int:
    """Measured phases the firmware's controller `controller_id` drives (3 or 6; 0 for off)."""
    for info in CONTROLLERS:
        if info.id == controller_id:
            return info.phases
    raise FirmwareConfigError(f"controller_id {controller_id!r}: unknown to the firmware")


def _error_text(rc: int) -> str:
    """Meaning of a negative return code of the firmware's configuration calls (HIL_FW_E_*)."""
    _, lib = _load()
    texts = {
        lib.HIL_FW_E_PARAM_ID: "unknown id",
        lib.HIL_FW_E_PARAM_VALUE: "value not finite or outside its physical range",
        lib.HIL_FW_E_CONTROLLER_ID: "unknown controller id",
        lib.HIL_FW_E_NOT_IMPLEMENTED: "controller not implemented in this firmware",
        lib.HIL_FW_E_MODE: "unknown setpoint mode",
        lib.HIL_FW_E_REFERENCE: "reference not finite",
        lib.HIL_FW_E_NULL: "null state",
    }
    return texts.get(rc, f"error {rc}")

# hil_fw_py_out_t: cmd {seq, n_states, vector_id, candidates, status, states[3], full_miss, mirror,
# durations_ns[3], torque_ref, id_ref, iq_ref, duty[6], n_duties} then split_ns[3]; native alignment, checked
# against cffi offsets.
_OUT = struct.Struct("@HBBBB3BBB3I3f6fB3I")


def _check_layout(ffi: Any) -> None:
    ok = (
        ffi.sizeof("hil_fw_py_out_t") == _OUT.size
        and ffi.offsetof("hil_fw_py_out_t", "split_ns") == _OUT.size - 12
        and ffi.offsetof("hil_fw_cmd_t", "durations_ns") == 12
        and ffi.offsetof("hil_fw_cmd_t", "torque_ref") == 24
        and ffi.offsetof("hil_fw_cmd_t", "full_miss") == 9
        and ffi.offsetof("hil_fw_cmd_t", "mirror") == 10
        and ffi.offsetof("hil_fw_cmd_t", "n_duties") == 60
    )
    if not ok:  # pragma: no cover - only on an exotic ABI
        raise FirmwareBuildError("hil_fw_py_out_t layout differs from the wrapper's struct format")


class Firmware:
    """One instance of the C reference firmware (controller off and disabled after construction)."""

    def __init__(self) -> None:
        ffi, lib = _load()
        _check_layout(ffi)
        self._ffi = ffi
        self._lib = lib
        self._state = ffi.new("hil_fw_state_t *")
        self._meas = ffi.new("hil_fw_meas_t *")
        self._out = ffi.new("hil_fw_py_out_t *")
        self._out_buf = ffi.buffer(self._out)
        self._unpack = _OUT.unpack_from
        self._py_step = lib.hil_fw_py_step
        lib.hil_fw_init(self._state)

    def set_param(self, param_id: int, value: float) -> None:
        """Set parameter `param_id` (ids of docs/architecture.md) to `value` in SI units."""
        name = _PARAM_NAME_OF.get(param_id, f"param_id {param_id}")
        try:
            fval = float(value)
            rc = self._lib.hil_fw_set_param(self._state, param_id, fval)
        except (TypeError, ValueError, OverflowError) as exc:
            raise FirmwareConfigError(f"{name}: cannot set to {value!r} ({exc})") from None
        if rc != self._lib.HIL_FW_OK:
            raise FirmwareConfigError(f"{name}: {_error_text(rc)} (value {value!r})")

    def get_param(self, param_id: int) -> float:
        """Current value of parameter `param_id` (float32 as stored by the firmware)."""
        out = self._ffi.new("float *")
        try:
            rc = self._lib.hil_fw_get_param(self._state, param_id, out)
        except (TypeError, OverflowError):
            rc = self._lib.HIL_FW_E_PARAM_ID
        if rc != self._lib.HIL_FW_OK:
            raise FirmwareConfigError(f"param_id {param_id!r}: {_error_text(rc)}")
        return float(out[0])

    def select_controller(self, controller_id: int) -> None:
        """Select the control law; unknown or unimplemented ids keep the previous one."""
        try:
            rc = self._lib.hil_fw_select_controller(self._state, controller_id)
        except (TypeError, OverflowError):
            rc = self._lib.HIL_FW_E_CONTROLLER_ID
        if rc != self._lib.HIL_FW_OK:
            raise FirmwareConfigError(f"controller_id {controller_id!r}: {_error_text(rc)}")

    def set_setpoint(self, enable: bool, mode: int, reference: float) -> None:
        """Enable/disable; mode 0: speed reference in rad/s (mechanical), 1: torque in N·m."""
        try:
            rc = self._lib.hil_fw_set_setpoint(self._state, 1 if enable else 0, mode, float(reference))
        except (TypeError, ValueError, OverflowError):
            rc = self._lib.HIL_FW_E_MODE
        if rc == self._lib.HIL_FW_E_REFERENCE:
            raise FirmwareConfigError(f"reference {reference!r}: not finite")
        if rc != self._lib.HIL_FW_OK:
            raise FirmwareConfigError(f"mode {mode!r} / reference {reference!r}: {_error_text(rc)}")

    @property
    def controller_id(self) -> int:
        """Selected controller id."""
        return int(self._state.controller_id)

    @property
    def enabled(self) -> bool:
        """True while the closed loop runs."""
        return bool(self._state.enable)

    @staticmethod
    def controller_implemented(controller_id: int) -> bool:
        """True if this firmware build implements `controller_id` (0 `off` included)."""
        _, lib = _load()
        if not 0 <= controller_id <= 255:
            return False
        return bool(lib.hil_fw_controller_implemented(controller_id))

    def step(
        self,
        seq: int,
        i_abc: Sequence[float],
        theta_e: float,
        omega_m: float,
        vdc: float,
        t_ns: int,
    ) -> FirmwareCommand:
        """Run one profiled control step on measurement k (phase currents A, angle rad electrical,
        speed rad/s mechanical, DC link V (<= 0: use the vdc param), sample time ns)."""
        n = len(i_abc)
        try:
            if n == 3:
                self._py_step(self._state, self._meas, self._out, seq, 3, i_abc[0], i_abc[1], i_abc[2],
                              0.0, 0.0, 0.0, theta_e, omega_m, vdc, t_ns)
            elif n == 6:
                self._py_step(self._state, self._meas, self._out, seq, 6, *i_abc, theta_e, omega_m, vdc,
                              t_ns)
            else:
                raise FirmwareInputError(f"i_abc: expected 3 or 6 phase currents, got {n}")
        except (TypeError, OverflowError) as exc:
            detail = _describe_bad_input(seq, i_abc, theta_e, omega_m, vdc, t_ns, exc)
            raise FirmwareInputError(detail) from None
        u = self._unpack(self._out_buf)
        ns = u[1]
        nd = u[22]
        return FirmwareCommand(
            u[0], u[5:5 + ns], u[10:10 + ns], u[2], u[3], u[4], u[23] + u[24] + u[25], (u[23], u[24], u[25]),
            u[13], u[14], u[15], u[8], u[9] == 1, u[16:16 + nd] if nd in (3, 6) else (),
        )


def _describe_bad_input(
    seq: object, i_abc: Sequence[object], theta_e: object, omega_m: object, vdc: object, t_ns: object,
    exc: Exception,
) -> str:
    """Name the first step argument cffi could not convert."""
    checks: list[tuple[str, object, int]] = [("seq", seq, 16), ("t_ns", t_ns, 64)]
    for name, value, bits in checks:
        if not isinstance(value, int) or not 0 <= value < (1 << bits):
            return f"{name}: expected an integer in [0, 2**{bits}), got {value!r}"
    named: list[tuple[str, object]] = [(f"i_abc[{k}]", v) for k, v in enumerate(i_abc)]
    named += [("theta_e", theta_e), ("omega_m", omega_m), ("vdc", vdc)]
    for name, value in named:
        try:
            float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return f"{name}: expected a number, got {value!r}"
    return f"step input rejected: {exc}"
