"""The Python numbering (ids.py) agrees with the DBC value tables and docs/architecture.md."""

from __future__ import annotations

from pmsm_hil.protocol.ids import (
    CONTROLLER_NAMES,
    PARAM_NAMES,
    STATUS_NAMES,
    ControllerId,
    Mode,
    Node,
    NodeState,
    ParamId,
    Status,
)
from pmsm_hil.protocol.layout import load_database

DB = load_database()


def choices(message: str, signal: str) -> dict[int, str]:
    sig = DB.get_message_by_name(message).get_signal_by_name(signal)
    return {int(k): str(v) for k, v in sig.choices.items()}


def test_controller_ids() -> None:
    assert choices("Setpoint", "controller_id") == {int(k): v for k, v in CONTROLLER_NAMES.items()}
    assert set(CONTROLLER_NAMES) == set(ControllerId)
    assert CONTROLLER_NAMES[ControllerId(10)] == "3vmpc" and int(ControllerId.HV_MPFC) == 11


def test_modes_params_status_nodes() -> None:
    assert choices("Setpoint", "mode") == {m.value: m.name.lower() for m in Mode}
    for msg in ("ConfigParam", "ConfigAck"):
        assert choices(msg, "param_id") == {int(k): v for k, v in PARAM_NAMES.items()}
    assert int(ParamId.CURRENT_LIMIT) == 22 and PARAM_NAMES[ParamId.PSI_F] == "psi_f"
    status = {int(k): v for k, v in STATUS_NAMES.items()}
    for msg, sig in (
        ("MeasB", "status"),
        ("MeasFd", "status"),
        ("CmdC", "status"),
        ("CmdFd", "status"),
        ("ConfigAck", "status"),
        ("FaultHost", "code"),
        ("FaultTarget", "code"),
    ):
        assert choices(msg, sig) == status, msg
    assert (int(Status.INVALID_CONFIG), int(Status.NOT_IMPLEMENTED)) == (5, 6)
    for msg in ("HeartbeatHost", "HeartbeatTarget", "FaultHost", "FaultTarget"):
        assert choices(msg, "node") == {n.value: n.name.lower() for n in Node}
    assert choices("HeartbeatHost", "state") == {s.value: s.name.lower() for s in NodeState}


def test_priority_order_of_ids() -> None:
    ids = {m.name: m.frame_id for m in DB.messages}
    fault = max(ids["FaultHost"], ids["FaultTarget"])
    hot = [ids[n] for n in ("MeasA", "MeasB", "MeasFd", "CmdA", "CmdB", "CmdC", "CmdFd", "Meas6A", "Meas6C",
                            "Meas6B", "MeasFd6")]
    slow = [ids[n] for n in ("Setpoint", "ConfigParam", "ConfigAck")]
    beat = min(ids["HeartbeatHost"], ids["HeartbeatTarget"])
    assert fault < min(hot) and max(hot) < min(slow) and max(slow) < beat
    assert all(i < 0x800 for i in ids.values())
    # six-phase measurement on the ids reserved for it, below the commands
    assert (ids["Meas6A"], ids["Meas6C"], ids["Meas6B"], ids["MeasFd6"]) == (0x102, 0x103, 0x104, 0x109)
    assert max(ids[n] for n in ("Meas6A", "Meas6C", "Meas6B", "MeasFd6")) < ids["CmdA"]
