"""The ids are generated from the DBC value tables (src/pmsm_hil/protocol/ids.py, firmware_stub/generated/hil_ids.h):
they agree with the signals' VAL_ tables, are not stale, and the generator refuses drifting tables."""

from __future__ import annotations

import re
from typing import Any

import cantools
import pytest

from pmsm_hil.protocol import gen_c, gen_ids
from pmsm_hil.protocol.errors import DatabaseError
from pmsm_hil.protocol.ids import (
    CONTROLLER_NAMES,
    PARAM_DOCS,
    PARAM_NAMES,
    PARAM_UNITS,
    RESERVED_CONTROLLER_IDS,
    STATUS_NAMES,
    ControllerId,
    Mode,
    Node,
    NodeState,
    ParamId,
    Status,
)
from pmsm_hil.protocol.layout import DBC_PATH, load_database
from pmsm_hil.protocol.paths import GENERATED_C_DIR

DB = load_database()


def choices(message: str, signal: str) -> dict[int, str]:
    sig = DB.get_message_by_name(message).get_signal_by_name(signal)
    return {int(k): str(v) for k, v in sig.choices.items()}


def _db(text: str) -> Any:
    return cantools.database.load_string(text, database_format="dbc")


def test_controller_ids() -> None:
    assert choices("Setpoint", "controller_id") == {int(k): v for k, v in CONTROLLER_NAMES.items()}
    assert set(CONTROLLER_NAMES) == set(ControllerId)
    assert CONTROLLER_NAMES[ControllerId(10)] == "3vmpc" and int(ControllerId.HV_MPFC) == 11
    # the label of a foreign firmware's controller: a DBC name and id, reserved (outside the counted ids)
    assert CONTROLLER_NAMES[ControllerId.EXTERNAL] == "external" and int(ControllerId.EXTERNAL) == 255
    assert {ControllerId.EXTERNAL} == RESERVED_CONTROLLER_IDS


def test_modes_params_status_nodes() -> None:
    assert choices("Setpoint", "mode") == {m.value: m.name.lower() for m in Mode}
    for msg in ("ConfigParam", "ConfigAck"):
        assert choices(msg, "param_id") == {int(k): v for k, v in PARAM_NAMES.items()}
    assert int(ParamId.CURRENT_LIMIT) == 22 and PARAM_NAMES[ParamId.PSI_F] == "psi_f"
    assert PARAM_UNITS[ParamId.RS] == "Ohm" and PARAM_UNITS[ParamId.SPEED_KP] == "N*m/(rad/s)"
    assert PARAM_DOCS[ParamId.LLS] == "leakage inductance" and set(PARAM_DOCS) == set(ParamId)
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


def test_generated_ids_not_stale() -> None:
    assert gen_c.stale_files(GENERATED_C_DIR) == []
    header = (GENERATED_C_DIR / gen_ids.C_HEADER).read_text(encoding="utf-8")
    macros = dict(re.findall(r"#define (HIL_FW_\w+) +(\S+)", header))
    for cid, name in CONTROLLER_NAMES.items():
        macro = "HIL_FW_CTRL_" + name.upper().replace("-", "_")
        assert macros[macro] == str(int(cid)) and macros[macro + "_NAME"] == f'"{name}"'
    counted = set(ControllerId) - RESERVED_CONTROLLER_IDS
    assert macros["HIL_FW_CTRL_COUNT"] == str(max(counted) + 1) == "13"  # 255 external does not size the tables
    assert macros["HIL_FW_CTRL_EXTERNAL"] == "255" and macros["HIL_FW_CTRL_EXTERNAL_NAME"] == '"external"'
    assert macros["HIL_FW_P_COUNT"] == str(max(ParamId) + 1)
    assert "/* stator resistance [Ohm] */" in header


def test_check_fails_on_a_stale_ids_module(tmp_path: Any) -> None:
    ids_py = tmp_path / "ids.py"
    gen_c.write(tmp_path, ids_py)
    assert gen_c.main(["--check", "--output-dir", str(tmp_path), "--ids-py", str(ids_py)]) == 0
    ids_py.write_text(ids_py.read_text(encoding="utf-8").replace("HV_MPFC = 11", "HV_MPFC = 12"), encoding="utf-8")
    assert gen_c.main(["--check", "--output-dir", str(tmp_path), "--ids-py", str(ids_py)]) == 1
    (tmp_path / gen_ids.C_HEADER).unlink()
    assert gen_c.stale_files(tmp_path, ids_py) == [str(tmp_path / gen_ids.C_HEADER), str(ids_py)]


def test_a_new_controller_in_the_dbc_reaches_c_and_python() -> None:
    text = DBC_PATH.read_text(encoding="utf-8").replace('12 "im-foc" ;', '12 "im-foc" 13 "my-ctrl" ;')
    text = text.replace('12 "im-foc" 255 "external" ;', '12 "im-foc" 13 "my-ctrl" 255 "external" ;')
    header, module = gen_ids.render(_db(text))
    assert re.search(r"#define HIL_FW_CTRL_MY_CTRL +13\n#define HIL_FW_CTRL_MY_CTRL_NAME +\"my-ctrl\"", header)
    assert re.search(r"#define HIL_FW_CTRL_COUNT +14", header)
    assert "    MY_CTRL = 13\n" in module and 'ControllerId.MY_CTRL: "my-ctrl",' in module
    namespace: dict[str, Any] = {}
    exec(compile(module, "ids.py", "exec"), namespace)  # the generated module runs
    assert namespace["CONTROLLER_NAMES"][namespace["ControllerId"](13)] == "my-ctrl"


@pytest.mark.parametrize(
    ("old", "new", "error"),
    [
        # the signal's VAL_ no longer repeats the family table
        ('VAL_ 512 controller_id 0 "off" 1 "mpcc"', 'VAL_ 512 controller_id 0 "off" 1 "mpc"', "Setpoint.controller_id"),
        # the family gains an id that no signal knows
        ('12 "im-foc" ;', '12 "im-foc" 13 "x" ;', "controller_id"),
        ('VAL_TABLE_ Node 0 "host" 1 "target" ;', "", "Node missing"),
        ('35 "psi_r_ref" ;\nVAL_TABLE_ ParamUnit', '35 "psi_r_ref" 36 "p" ;\nVAL_TABLE_ ParamUnit', "ParamUnit"),
        ('VAL_TABLE_ Mode 0 "speed" 1 "torque" ;', 'VAL_TABLE_ Mode 0 "speed" 1 "Torque" ;', "Mode"),
        # the signal drops the reserved id, or the reserved id falls inside the counted range
        ('12 "im-foc" 255 "external" ;', '12 "im-foc" ;', "Setpoint.controller_id"),
        ('ControllerIdReserved 255 "external" ;', 'ControllerIdReserved 11 "external" ;', "not above the ids"),
        ('ControllerIdReserved 255 "external" ;', 'ControllerIdReserved 255 "mpcc" ;', "not unique"),
        ('VAL_TABLE_ Enable 0 "disabled" 1 "enabled" ;', "", "Enable missing"),
        # a value description drifts from its signals; an unknown table
        ('VAL_TABLE_ Mirror 0 "plain" 1 "mirrored" ;', 'VAL_TABLE_ Mirror 0 "plain" 1 "mirror" ;', "CmdC.mirror"),
        ('VAL_TABLE_ Enable 0', 'VAL_TABLE_ Spare 0 "x" ;\nVAL_TABLE_ Enable 0', "Spare is not known"),
    ],
)
def test_generator_refuses_drifting_tables(old: str, new: str, error: str) -> None:
    text = DBC_PATH.read_text(encoding="utf-8")
    assert old in text
    with pytest.raises(DatabaseError, match=error):
        gen_ids.render(_db(text.replace(old, new, 1)))


def test_python_member_of_a_name_starting_with_a_digit() -> None:
    assert gen_ids.py_member("3vmpc") == "MPC_3V" and gen_ids.py_member("fcs-mpc-1") == "FCS_MPC_1"
    with pytest.raises(DatabaseError, match="PY_MEMBER"):
        gen_ids.py_member("2foo")
