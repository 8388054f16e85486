"""src/pmsm_hil/protocol/hil.dbc as DBC tools read it: strict load, a strict cantools round trip of every signal over
its whole range, ranges that cover the raw values in use, a comment on every signal, the value descriptions
and the attributes (bus type, cycle times)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import cantools
import pytest
from cantools.database.errors import EncodeError

from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.protocol.layout import DBC_PATH

DB: Any = cantools.database.load_file(str(DBC_PATH), strict=True)
MESSAGES = list(DB.messages)
FLT_MAX = 3.4028234663852886e38
#: (message, signal) -> raw range in use, where it is narrower than the bits on purpose (other raw values are
#: invalid frames or rejected values: n_states 0, an enable or mode byte other than 0/1)
NARROWER = {("CmdA", "n_states"): (1, 3), ("CmdFd", "n_states"): (1, 3), ("Setpoint", "enable"): (0, 1),
            ("Setpoint", "mode"): (0, 1), ("CmdDutyC", "n_duties"): (3, 6), ("CmdDutyFd", "n_duties"): (3, 6)}
#: messages sent once per control period
PER_PERIOD = {"MeasA", "MeasB", "Meas6A", "Meas6B", "Meas6C", "MeasFd", "MeasFd6", "CmdA", "CmdB", "CmdC", "CmdFd",
              "CmdDutyA", "CmdDutyB", "CmdDutyC", "CmdDutyFd"}


def _raw_range(sig: Any) -> tuple[int, int]:
    if sig.is_signed:
        return -(1 << (sig.length - 1)), (1 << (sig.length - 1)) - 1
    return 0, (1 << sig.length) - 1


def _phys(sig: Any, raw: int) -> float:
    return float(raw * sig.scale + sig.offset)


def _test_values(sig: Any) -> list[float]:
    """min, max and values in between, as the physical values of raw integers (floats: exact float32 values)."""
    if sig.is_float:
        return [sig.minimum, -(2.0**-100), -2.5, 0.0, 0.375, 4.5e6, sig.maximum]
    lo = round((sig.minimum - sig.offset) / sig.scale)
    hi = round((sig.maximum - sig.offset) / sig.scale)
    raws = sorted({lo, hi, lo + 1, hi - 1, (lo + hi) // 2, lo + (hi - lo) // 3, 0 if lo <= 0 <= hi else lo})
    return [_phys(sig, r) for r in raws if lo <= r <= hi]


def _baseline(msg: Any) -> dict[str, float]:
    return {s.name: (s.minimum if s.minimum is not None else 0.0) for s in msg.signals}


def test_loads_strict_and_fd_frames_are_marked() -> None:
    assert len(MESSAGES) == 22 and sum(len(m.signals) for m in MESSAGES) == 114
    for msg in MESSAGES:
        assert msg.is_fd == (msg.length > 8), msg.name  # VFrameFormat StandardCAN_FD exactly on the long frames


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: m.name)
def test_every_signal_round_trips_strict_over_its_range(msg: Any) -> None:
    for sig in msg.signals:
        for value in _test_values(sig):
            data = msg.encode({**_baseline(msg), sig.name: value}, strict=True)
            assert len(data) == msg.length
            back = msg.decode(data, decode_choices=False, scaling=False)[sig.name]
            if sig.is_float:
                assert back == value, (msg.name, sig.name, value)  # the test values are exact float32
            else:
                assert back == round((value - sig.offset) / sig.scale), (msg.name, sig.name, value)
                assert msg.decode(data, decode_choices=False)[sig.name] == pytest.approx(value, rel=1e-12)


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: m.name)
def test_ranges_cover_the_raw_values_in_use(msg: Any) -> None:
    for sig in msg.signals:
        if sig.is_float:
            assert (sig.minimum, sig.maximum) == (-FLT_MAX, FLT_MAX), f"{msg.name}.{sig.name}: every finite float32"
            continue
        lo, hi = NARROWER.get((msg.name, sig.name), _raw_range(sig))
        assert sig.minimum == _phys(sig, lo), f"{msg.name}.{sig.name} min"
        assert sig.maximum == _phys(sig, hi), f"{msg.name}.{sig.name} max"  # exactly the largest raw value


def test_angles_up_to_the_largest_raw_value_encode_strict() -> None:
    msg = DB.get_message_by_name("MeasFd")
    for theta in (6.2830894, 65535 * 2 * math.pi / 65536):  # the reported angle; raw 65535
        data = msg.encode({**_baseline(msg), "theta_e": theta}, strict=True)
        assert msg.decode(data, scaling=False)["theta_e"] == 65535
    with pytest.raises(EncodeError):  # rounds to raw 65536: a sender wraps it to 0 (docs/protocol.md)
        msg.encode({**_baseline(msg), "theta_e": 2 * math.pi - 1e-6}, strict=True)


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: m.name)
def test_every_signal_has_a_comment_naming_its_unit(msg: Any) -> None:
    for sig in msg.signals:
        assert sig.comment and len(sig.comment) > 20, f"{msg.name}.{sig.name} has no comment"
        if sig.unit:
            assert sig.unit in sig.comment, f"{msg.name}.{sig.name}: comment lacks the unit {sig.unit}"


def _choices(message: str, signal: str) -> dict[int, str]:
    sig = DB.get_message_by_name(message).get_signal_by_name(signal)
    return {int(k): str(v) for k, v in (sig.choices or {}).items()}


def test_value_descriptions_for_tools() -> None:
    assert _choices("Setpoint", "enable") == {0: "disabled", 1: "enabled"}
    assert _choices("Setpoint", "controller_id")[255] == "external"
    for msg in ("CmdC", "CmdFd"):
        assert _choices(msg, "mirror") == {0: "plain", 1: "mirrored"}
        assert _choices(msg, "exec_time_ns") == {0: "not measured", 4294967295: "saturated"}
    states = _choices("CmdFd", "state0")
    assert all(_choices(m, f"state{k}") == states for m in ("CmdA", "CmdFd") for k in range(3))
    # names "Vj SaSbSc": the bits of the code, and j from the direction of the code's voltage
    # v = Vdc/3 (2Sa - Sb - Sc, sqrt(3) (Sb - Sc)): Vj (j = 1..6) at (j - 1) * 60 degrees, V0/V7 the zeros
    for code in range(8):
        sa, sb, sc = code >> 2 & 1, code >> 1 & 1, code & 1
        va, vb = 2 * sa - sb - sc, math.sqrt(3) * (sb - sc)
        j = {0: 0, 7: 7}.get(code, round(math.degrees(math.atan2(vb, va)) / 60) % 6 + 1)
        assert states[code] == f"V{j} {sa}{sb}{sc}"


def test_attributes_bus_type_and_cycle_times() -> None:
    attrs = DB.dbc.attributes
    assert attrs["BusType"].value == "CAN FD"
    ts_default = next(f.default for f in dataclasses.fields(RunConfig) if f.name == "ts_s")
    assert isinstance(ts_default, float)
    assert attrs["HilControlPeriodNs"].value == round(ts_default * 1e9) == 100_000  # the host's default Ts
    for msg in MESSAGES:
        msg_attrs = msg.dbc.attributes
        per_period = msg_attrs["HilPerControlPeriod"].value if "HilPerControlPeriod" in msg_attrs else 0
        assert per_period == (1 if msg.name in PER_PERIOD else 0), msg.name
        # Ts (0.1 ms by default, set per run) is no whole number of ms: no fixed millisecond cycle anywhere
        assert msg.cycle_time in (None, 0), msg.name
