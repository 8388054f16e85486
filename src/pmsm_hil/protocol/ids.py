"""Shared numbering: controller ids, setpoint modes, config parameters, status codes, nodes.

Generated from the VAL_TABLE_ entries of src/pmsm_hil/protocol/hil.dbc by
`python -m pmsm_hil.protocol.gen_c`; do not edit (CI runs it with --check). The C side is
firmware_stub/generated/hil_ids.h. Parameter values are float32 in the SI units of PARAM_UNITS
("-": dimensionless or a code); PARAM_DOCS says what each parameter is."""

from __future__ import annotations

from enum import IntEnum


class ControllerId(IntEnum):
    """Values of `controller_id` in the DBC; names in `CONTROLLER_NAMES`."""

    OFF = 0
    MPCC = 1
    FCS_MPC_1 = 2
    FCS_MPC_2 = 3
    DSVM_20 = 4
    DBCC_MPC = 5
    FOC = 6
    MPTC1 = 7
    MPTC2 = 8
    MPTC3 = 9
    MPC_3V = 10
    HV_MPFC = 11
    IM_FOC = 12
    EXTERNAL = 255


CONTROLLER_NAMES: dict[ControllerId, str] = {
    ControllerId.OFF: "off",
    ControllerId.MPCC: "mpcc",
    ControllerId.FCS_MPC_1: "fcs-mpc-1",
    ControllerId.FCS_MPC_2: "fcs-mpc-2",
    ControllerId.DSVM_20: "dsvm-20",
    ControllerId.DBCC_MPC: "dbcc-mpc",
    ControllerId.FOC: "foc",
    ControllerId.MPTC1: "mptc1",
    ControllerId.MPTC2: "mptc2",
    ControllerId.MPTC3: "mptc3",
    ControllerId.MPC_3V: "3vmpc",
    ControllerId.HV_MPFC: "hv-mpfc",
    ControllerId.IM_FOC: "im-foc",
    ControllerId.EXTERNAL: "external",
}

#: reserved ids (ControllerIdReserved): named by the protocol, not counted in HIL_FW_CTRL_COUNT
RESERVED_CONTROLLER_IDS: frozenset[ControllerId] = frozenset({ControllerId.EXTERNAL})


class Mode(IntEnum):
    """Values of `mode` in the DBC; names in `MODE_NAMES`."""

    SPEED = 0
    TORQUE = 1


MODE_NAMES: dict[Mode, str] = {
    Mode.SPEED: "speed",
    Mode.TORQUE: "torque",
}


class ParamId(IntEnum):
    """Values of `param_id` in the DBC; names in `PARAM_NAMES`."""

    RS = 1
    LD = 2
    LQ = 3
    PSI_F = 4
    POLE_PAIRS = 5
    TS = 6
    VDC = 7
    SPEED_KP = 8
    SPEED_KI = 9
    TORQUE_LIMIT = 10
    TORQUE_INTEGRATOR_INIT = 11
    ID_REF = 12
    LAMBDA = 13
    T_THR = 14
    T_DEAD = 15
    T_MPW = 16
    FLUX_REF = 17
    CURRENT_KP = 18
    CURRENT_KI = 19
    LLS = 20
    TORQUE_BAND = 21
    CURRENT_LIMIT = 22
    ZERO_SELECT = 23
    DT_COMP = 24
    FCS_READING = 25
    V3_SYMMETRIC = 26
    PWM_DUTIES = 27
    RR = 32
    LSIGMA = 33
    LM = 34
    PSI_R_REF = 35


PARAM_NAMES: dict[ParamId, str] = {
    ParamId.RS: "rs",
    ParamId.LD: "ld",
    ParamId.LQ: "lq",
    ParamId.PSI_F: "psi_f",
    ParamId.POLE_PAIRS: "pole_pairs",
    ParamId.TS: "ts",
    ParamId.VDC: "vdc",
    ParamId.SPEED_KP: "speed_kp",
    ParamId.SPEED_KI: "speed_ki",
    ParamId.TORQUE_LIMIT: "torque_limit",
    ParamId.TORQUE_INTEGRATOR_INIT: "torque_integrator_init",
    ParamId.ID_REF: "id_ref",
    ParamId.LAMBDA: "lambda",
    ParamId.T_THR: "t_thr",
    ParamId.T_DEAD: "t_dead",
    ParamId.T_MPW: "t_mpw",
    ParamId.FLUX_REF: "flux_ref",
    ParamId.CURRENT_KP: "current_kp",
    ParamId.CURRENT_KI: "current_ki",
    ParamId.LLS: "lls",
    ParamId.TORQUE_BAND: "torque_band",
    ParamId.CURRENT_LIMIT: "current_limit",
    ParamId.ZERO_SELECT: "zero_select",
    ParamId.DT_COMP: "dt_comp",
    ParamId.FCS_READING: "fcs_reading",
    ParamId.V3_SYMMETRIC: "v3_symmetric",
    ParamId.PWM_DUTIES: "pwm_duties",
    ParamId.RR: "rr",
    ParamId.LSIGMA: "lsigma",
    ParamId.LM: "lm",
    ParamId.PSI_R_REF: "psi_r_ref",
}

PARAM_UNITS: dict[ParamId, str] = {
    ParamId.RS: "Ohm",
    ParamId.LD: "H",
    ParamId.LQ: "H",
    ParamId.PSI_F: "Wb",
    ParamId.POLE_PAIRS: "-",
    ParamId.TS: "s",
    ParamId.VDC: "V",
    ParamId.SPEED_KP: "N*m/(rad/s)",
    ParamId.SPEED_KI: "N*m/rad",
    ParamId.TORQUE_LIMIT: "N*m",
    ParamId.TORQUE_INTEGRATOR_INIT: "N*m",
    ParamId.ID_REF: "A",
    ParamId.LAMBDA: "-",
    ParamId.T_THR: "s",
    ParamId.T_DEAD: "s",
    ParamId.T_MPW: "s",
    ParamId.FLUX_REF: "Wb",
    ParamId.CURRENT_KP: "V/A",
    ParamId.CURRENT_KI: "V/(A*s)",
    ParamId.LLS: "H",
    ParamId.TORQUE_BAND: "N*m",
    ParamId.CURRENT_LIMIT: "A",
    ParamId.ZERO_SELECT: "-",
    ParamId.DT_COMP: "-",
    ParamId.FCS_READING: "-",
    ParamId.V3_SYMMETRIC: "-",
    ParamId.PWM_DUTIES: "-",
    ParamId.RR: "Ohm",
    ParamId.LSIGMA: "H",
    ParamId.LM: "H",
    ParamId.PSI_R_REF: "Wb",
}

PARAM_DOCS: dict[ParamId, str] = {
    ParamId.RS: "stator resistance",
    ParamId.LD: "d-axis inductance",
    ParamId.LQ: "q-axis inductance",
    ParamId.PSI_F: "magnet flux linkage",
    ParamId.POLE_PAIRS: "pole pairs (integer)",
    ParamId.TS: "control period",
    ParamId.VDC: "nominal DC-link voltage",
    ParamId.SPEED_KP: "speed PI proportional gain",
    ParamId.SPEED_KI: "speed PI integral gain",
    ParamId.TORQUE_LIMIT: "torque reference limit",
    ParamId.TORQUE_INTEGRATOR_INIT: "speed PI integrator preset at enable",
    ParamId.ID_REF: "d-axis current reference",
    ParamId.LAMBDA: "cost weighting factor",
    ParamId.T_THR: "threshold time",
    ParamId.T_DEAD: "inverter dead time",
    ParamId.T_MPW: "minimum pulse width",
    ParamId.FLUX_REF: "stator flux reference",
    ParamId.CURRENT_KP: "current PI proportional gain",
    ParamId.CURRENT_KI: "current PI integral gain",
    ParamId.LLS: "leakage inductance",
    ParamId.TORQUE_BAND: "torque hysteresis band",
    ParamId.CURRENT_LIMIT: "current magnitude limit",
    ParamId.ZERO_SELECT: "zero-vector rule of 3vmpc/hv-mpfc: 0 paper, 1 min_transitions",
    ParamId.DT_COMP: "pulse-based dead-time compensation in 3vmpc/hv-mpfc: 0 off, 1 on",
    ParamId.FCS_READING: "fcs-mpc-1/2 reading of Tables 1/2, bit flags (docs/algorithms/fcs_mpc_regions.md)",
    ParamId.V3_SYMMETRIC: "mptc2/mptc3 send each V3 as G1/2-G2-G1/2 (mirrored command): 0 off, 1 on",
    ParamId.PWM_DUTIES: "foc output: 1 duty cycles (CmdDuty*), 0 the 5-segment switching states",
    ParamId.RR: "induction machine: rotor resistance RR of the inverse-Gamma model",
    ParamId.LSIGMA: "induction machine: leakage inductance L_sigma (inverse-Gamma)",
    ParamId.LM: "induction machine: magnetizing inductance L_M (inverse-Gamma)",
    ParamId.PSI_R_REF: "induction machine: rotor-flux reference of im-foc",
}


class Status(IntEnum):
    """Values of `code`, `status` in the DBC; names in `STATUS_NAMES`."""

    OK = 0
    OVERCURRENT = 1
    OVERSPEED = 2
    WATCHDOG = 3
    BAD_FRAME = 4
    INVALID_CONFIG = 5
    NOT_IMPLEMENTED = 6


STATUS_NAMES: dict[Status, str] = {
    Status.OK: "ok",
    Status.OVERCURRENT: "overcurrent",
    Status.OVERSPEED: "overspeed",
    Status.WATCHDOG: "watchdog",
    Status.BAD_FRAME: "bad_frame",
    Status.INVALID_CONFIG: "invalid_config",
    Status.NOT_IMPLEMENTED: "not_implemented",
}


class Node(IntEnum):
    """Values of `node` in the DBC; names in `NODE_NAMES`."""

    HOST = 0
    TARGET = 1


NODE_NAMES: dict[Node, str] = {
    Node.HOST: "host",
    Node.TARGET: "target",
}


class NodeState(IntEnum):
    """Values of `state` in the DBC; names in `NODE_STATE_NAMES`."""

    BOOT = 0
    IDLE = 1
    RUNNING = 2
    FAULT = 3


NODE_STATE_NAMES: dict[NodeState, str] = {
    NodeState.BOOT: "boot",
    NodeState.IDLE: "idle",
    NodeState.RUNNING: "running",
    NodeState.FAULT: "fault",
}
