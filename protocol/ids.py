"""Shared numbering (controller ids, setpoint modes, config parameters, status codes, nodes).

The DBC value tables (`hil.dbc`, VAL_) are the source; tests/protocol/test_ids.py checks these enums
and name tables against them, so a change in one place without the other fails CI."""

from __future__ import annotations

from enum import IntEnum


class ControllerId(IntEnum):
    """`Setpoint.controller_id`; the CLI names are in `CONTROLLER_NAMES`."""

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
}


class Mode(IntEnum):
    """`Setpoint.mode`: speed reference in rad/s (mechanical) or torque reference in N·m."""

    SPEED = 0
    TORQUE = 1


class ParamId(IntEnum):
    """`ConfigParam.param_id`; value float32 in SI units (unit in the comment)."""

    RS = 1  # Ω
    LD = 2  # H
    LQ = 3  # H
    PSI_F = 4  # Wb
    POLE_PAIRS = 5  # -
    TS = 6  # s
    VDC = 7  # V
    SPEED_KP = 8  # N·m/(rad/s)
    SPEED_KI = 9  # N·m/rad
    TORQUE_LIMIT = 10  # N·m
    TORQUE_INTEGRATOR_INIT = 11  # N·m
    ID_REF = 12  # A
    LAMBDA = 13  # weighting factor
    T_THR = 14  # s
    T_DEAD = 15  # s
    T_MPW = 16  # s
    FLUX_REF = 17  # Wb
    CURRENT_KP = 18  # V/A
    CURRENT_KI = 19  # V/(A·s)
    LLS = 20  # H
    TORQUE_BAND = 21  # N·m
    CURRENT_LIMIT = 22  # A
    ZERO_SELECT = 23  # 0 paper rule, 1 min_transitions (3vmpc, hv-mpfc)
    DT_COMP = 24  # 0 off, 1 pulse-based dead-time compensation (3vmpc, hv-mpfc)
    FCS_READING = 25  # fcs-mpc-1/2 reading of Tables 1/2, bit flags (docs/algorithms/fcs_mpc_regions.md)
    V3_SYMMETRIC = 26  # 0 off, 1 mptc2/mptc3 send each V3 as G1/2-G2-G1/2 (mirrored command)


PARAM_NAMES: dict[ParamId, str] = {p: p.name.lower() for p in ParamId}


class Status(IntEnum):
    """Status / fault codes (Measurement.status, Command.status, ConfigAck.status, Fault.code)."""

    OK = 0
    OVERCURRENT = 1
    OVERSPEED = 2
    WATCHDOG = 3
    BAD_FRAME = 4
    INVALID_CONFIG = 5
    NOT_IMPLEMENTED = 6


STATUS_NAMES: dict[Status, str] = {s: s.name.lower() for s in Status}


class Node(IntEnum):
    """Node numbers (Heartbeat.node, Fault.node)."""

    HOST = 0
    TARGET = 1


class NodeState(IntEnum):
    """`Heartbeat.state`."""

    BOOT = 0
    IDLE = 1
    RUNNING = 2
    FAULT = 3
