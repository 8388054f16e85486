/* Ids of the HIL protocol, generated from the VAL_TABLE_ entries of src/pmsm_hil/protocol/hil.dbc by
 * python -m pmsm_hil.protocol.gen_c. Do not edit: change the DBC and regenerate (CI checks with --check). */
#ifndef HIL_IDS_H
#define HIL_IDS_H

/* ControllerId: Setpoint.controller_id */
#define HIL_FW_CTRL_OFF            0
#define HIL_FW_CTRL_OFF_NAME       "off"
#define HIL_FW_CTRL_MPCC           1
#define HIL_FW_CTRL_MPCC_NAME      "mpcc"
#define HIL_FW_CTRL_FCS_MPC_1      2
#define HIL_FW_CTRL_FCS_MPC_1_NAME "fcs-mpc-1"
#define HIL_FW_CTRL_FCS_MPC_2      3
#define HIL_FW_CTRL_FCS_MPC_2_NAME "fcs-mpc-2"
#define HIL_FW_CTRL_DSVM_20        4
#define HIL_FW_CTRL_DSVM_20_NAME   "dsvm-20"
#define HIL_FW_CTRL_DBCC_MPC       5
#define HIL_FW_CTRL_DBCC_MPC_NAME  "dbcc-mpc"
#define HIL_FW_CTRL_FOC            6
#define HIL_FW_CTRL_FOC_NAME       "foc"
#define HIL_FW_CTRL_MPTC1          7
#define HIL_FW_CTRL_MPTC1_NAME     "mptc1"
#define HIL_FW_CTRL_MPTC2          8
#define HIL_FW_CTRL_MPTC2_NAME     "mptc2"
#define HIL_FW_CTRL_MPTC3          9
#define HIL_FW_CTRL_MPTC3_NAME     "mptc3"
#define HIL_FW_CTRL_3VMPC          10
#define HIL_FW_CTRL_3VMPC_NAME     "3vmpc"
#define HIL_FW_CTRL_HV_MPFC        11
#define HIL_FW_CTRL_HV_MPFC_NAME   "hv-mpfc"
#define HIL_FW_CTRL_IM_FOC         12
#define HIL_FW_CTRL_IM_FOC_NAME    "im-foc"
#define HIL_FW_CTRL_COUNT          13 /* largest id + 1 (size of arrays indexed by id) */
#define HIL_FW_CTRL_EXTERNAL       255 /* reserved (ControllerIdReserved): not counted in HIL_FW_CTRL_COUNT */
#define HIL_FW_CTRL_EXTERNAL_NAME  "external"

/* Mode: Setpoint.mode */
#define HIL_FW_MODE_SPEED       0
#define HIL_FW_MODE_SPEED_NAME  "speed"
#define HIL_FW_MODE_TORQUE      1
#define HIL_FW_MODE_TORQUE_NAME "torque"
#define HIL_FW_MODE_COUNT       2 /* largest id + 1 (size of arrays indexed by id) */

/* ParamId: ConfigParam.param_id, ConfigAck.param_id */
#define HIL_FW_P_RS                          1 /* stator resistance [Ohm] */
#define HIL_FW_P_RS_NAME                     "rs"
#define HIL_FW_P_LD                          2 /* d-axis inductance [H] */
#define HIL_FW_P_LD_NAME                     "ld"
#define HIL_FW_P_LQ                          3 /* q-axis inductance [H] */
#define HIL_FW_P_LQ_NAME                     "lq"
#define HIL_FW_P_PSI_F                       4 /* magnet flux linkage [Wb] */
#define HIL_FW_P_PSI_F_NAME                  "psi_f"
#define HIL_FW_P_POLE_PAIRS                  5 /* pole pairs (integer) [-] */
#define HIL_FW_P_POLE_PAIRS_NAME             "pole_pairs"
#define HIL_FW_P_TS                          6 /* control period [s] */
#define HIL_FW_P_TS_NAME                     "ts"
#define HIL_FW_P_VDC                         7 /* nominal DC-link voltage [V] */
#define HIL_FW_P_VDC_NAME                    "vdc"
#define HIL_FW_P_SPEED_KP                    8 /* speed PI proportional gain [N*m/(rad/s)] */
#define HIL_FW_P_SPEED_KP_NAME               "speed_kp"
#define HIL_FW_P_SPEED_KI                    9 /* speed PI integral gain [N*m/rad] */
#define HIL_FW_P_SPEED_KI_NAME               "speed_ki"
#define HIL_FW_P_TORQUE_LIMIT                10 /* torque reference limit [N*m] */
#define HIL_FW_P_TORQUE_LIMIT_NAME           "torque_limit"
#define HIL_FW_P_TORQUE_INTEGRATOR_INIT      11 /* speed PI integrator preset at enable [N*m] */
#define HIL_FW_P_TORQUE_INTEGRATOR_INIT_NAME "torque_integrator_init"
#define HIL_FW_P_ID_REF                      12 /* d-axis current reference [A] */
#define HIL_FW_P_ID_REF_NAME                 "id_ref"
#define HIL_FW_P_LAMBDA                      13 /* cost weighting factor [-] */
#define HIL_FW_P_LAMBDA_NAME                 "lambda"
#define HIL_FW_P_T_THR                       14 /* threshold time [s] */
#define HIL_FW_P_T_THR_NAME                  "t_thr"
#define HIL_FW_P_T_DEAD                      15 /* inverter dead time [s] */
#define HIL_FW_P_T_DEAD_NAME                 "t_dead"
#define HIL_FW_P_T_MPW                       16 /* minimum pulse width [s] */
#define HIL_FW_P_T_MPW_NAME                  "t_mpw"
#define HIL_FW_P_FLUX_REF                    17 /* stator flux reference [Wb] */
#define HIL_FW_P_FLUX_REF_NAME               "flux_ref"
#define HIL_FW_P_CURRENT_KP                  18 /* current PI proportional gain [V/A] */
#define HIL_FW_P_CURRENT_KP_NAME             "current_kp"
#define HIL_FW_P_CURRENT_KI                  19 /* current PI integral gain [V/(A*s)] */
#define HIL_FW_P_CURRENT_KI_NAME             "current_ki"
#define HIL_FW_P_LLS                         20 /* leakage inductance [H] */
#define HIL_FW_P_LLS_NAME                    "lls"
#define HIL_FW_P_TORQUE_BAND                 21 /* torque hysteresis band [N*m] */
#define HIL_FW_P_TORQUE_BAND_NAME            "torque_band"
#define HIL_FW_P_CURRENT_LIMIT               22 /* current magnitude limit [A] */
#define HIL_FW_P_CURRENT_LIMIT_NAME          "current_limit"
#define HIL_FW_P_ZERO_SELECT                 23 /* zero-vector rule of 3vmpc/hv-mpfc: 0 paper, 1 min_transitions [-] */
#define HIL_FW_P_ZERO_SELECT_NAME            "zero_select"
#define HIL_FW_P_DT_COMP                     24 /* pulse-based dead-time compensation in 3vmpc/hv-mpfc: 0 off, 1 on [-] */
#define HIL_FW_P_DT_COMP_NAME                "dt_comp"
#define HIL_FW_P_FCS_READING                 25 /* fcs-mpc-1/2 reading of Tables 1/2, bit flags (docs/algorithms/fcs_mpc_regions.md) [-] */
#define HIL_FW_P_FCS_READING_NAME            "fcs_reading"
#define HIL_FW_P_V3_SYMMETRIC                26 /* mptc2/mptc3 send each V3 as G1/2-G2-G1/2 (mirrored command): 0 off, 1 on [-] */
#define HIL_FW_P_V3_SYMMETRIC_NAME           "v3_symmetric"
#define HIL_FW_P_PWM_DUTIES                  27 /* foc output: 1 duty cycles (CmdDuty*), 0 the 5-segment switching states [-] */
#define HIL_FW_P_PWM_DUTIES_NAME             "pwm_duties"
#define HIL_FW_P_RR                          32 /* induction machine: rotor resistance RR of the inverse-Gamma model [Ohm] */
#define HIL_FW_P_RR_NAME                     "rr"
#define HIL_FW_P_LSIGMA                      33 /* induction machine: leakage inductance L_sigma (inverse-Gamma) [H] */
#define HIL_FW_P_LSIGMA_NAME                 "lsigma"
#define HIL_FW_P_LM                          34 /* induction machine: magnetizing inductance L_M (inverse-Gamma) [H] */
#define HIL_FW_P_LM_NAME                     "lm"
#define HIL_FW_P_PSI_R_REF                   35 /* induction machine: rotor-flux reference of im-foc [Wb] */
#define HIL_FW_P_PSI_R_REF_NAME              "psi_r_ref"
#define HIL_FW_P_COUNT                       36 /* largest id + 1 (size of arrays indexed by id) */

/* Status: FaultHost.code, FaultTarget.code, MeasB.status, Meas6B.status, MeasFd.status, MeasFd6.status,
 * CmdC.status, CmdFd.status, CmdDutyC.status, CmdDutyFd.status, ConfigAck.status */
#define HIL_FW_STATUS_OK                   0
#define HIL_FW_STATUS_OK_NAME              "ok"
#define HIL_FW_STATUS_OVERCURRENT          1
#define HIL_FW_STATUS_OVERCURRENT_NAME     "overcurrent"
#define HIL_FW_STATUS_OVERSPEED            2
#define HIL_FW_STATUS_OVERSPEED_NAME       "overspeed"
#define HIL_FW_STATUS_WATCHDOG             3
#define HIL_FW_STATUS_WATCHDOG_NAME        "watchdog"
#define HIL_FW_STATUS_BAD_FRAME            4
#define HIL_FW_STATUS_BAD_FRAME_NAME       "bad_frame"
#define HIL_FW_STATUS_INVALID_CONFIG       5
#define HIL_FW_STATUS_INVALID_CONFIG_NAME  "invalid_config"
#define HIL_FW_STATUS_NOT_IMPLEMENTED      6
#define HIL_FW_STATUS_NOT_IMPLEMENTED_NAME "not_implemented"
#define HIL_FW_STATUS_COUNT                7 /* largest id + 1 (size of arrays indexed by id) */

/* Node: FaultHost.node, FaultTarget.node, HeartbeatHost.node, HeartbeatTarget.node */
#define HIL_FW_NODE_HOST        0
#define HIL_FW_NODE_HOST_NAME   "host"
#define HIL_FW_NODE_TARGET      1
#define HIL_FW_NODE_TARGET_NAME "target"
#define HIL_FW_NODE_COUNT       2 /* largest id + 1 (size of arrays indexed by id) */

/* NodeState: HeartbeatHost.state, HeartbeatTarget.state */
#define HIL_FW_NODE_STATE_BOOT         0
#define HIL_FW_NODE_STATE_BOOT_NAME    "boot"
#define HIL_FW_NODE_STATE_IDLE         1
#define HIL_FW_NODE_STATE_IDLE_NAME    "idle"
#define HIL_FW_NODE_STATE_RUNNING      2
#define HIL_FW_NODE_STATE_RUNNING_NAME "running"
#define HIL_FW_NODE_STATE_FAULT        3
#define HIL_FW_NODE_STATE_FAULT_NAME   "fault"
#define HIL_FW_NODE_STATE_COUNT        4 /* largest id + 1 (size of arrays indexed by id) */

/* Frames of the DBC: HIL_FRAMES(X) expands X(id, length, target, command) for each message in id order
 * (the id and length macros of hil_protocol.h); target: its sender is the Target node; command: a Command
 * frame (Cmd*, `seq` in bytes 0-1) */
#define HIL_FRAMES(X) \
    X(HIL_PROTOCOL_FAULT_HOST_FRAME_ID, HIL_PROTOCOL_FAULT_HOST_LENGTH, 0, 0)             \
    X(HIL_PROTOCOL_FAULT_TARGET_FRAME_ID, HIL_PROTOCOL_FAULT_TARGET_LENGTH, 1, 0)         \
    X(HIL_PROTOCOL_MEAS_A_FRAME_ID, HIL_PROTOCOL_MEAS_A_LENGTH, 0, 0)                     \
    X(HIL_PROTOCOL_MEAS_B_FRAME_ID, HIL_PROTOCOL_MEAS_B_LENGTH, 0, 0)                     \
    X(HIL_PROTOCOL_MEAS6_A_FRAME_ID, HIL_PROTOCOL_MEAS6_A_LENGTH, 0, 0)                   \
    X(HIL_PROTOCOL_MEAS6_C_FRAME_ID, HIL_PROTOCOL_MEAS6_C_LENGTH, 0, 0)                   \
    X(HIL_PROTOCOL_MEAS6_B_FRAME_ID, HIL_PROTOCOL_MEAS6_B_LENGTH, 0, 0)                   \
    X(HIL_PROTOCOL_MEAS_FD_FRAME_ID, HIL_PROTOCOL_MEAS_FD_LENGTH, 0, 0)                   \
    X(HIL_PROTOCOL_MEAS_FD6_FRAME_ID, HIL_PROTOCOL_MEAS_FD6_LENGTH, 0, 0)                 \
    X(HIL_PROTOCOL_CMD_A_FRAME_ID, HIL_PROTOCOL_CMD_A_LENGTH, 1, 1)                       \
    X(HIL_PROTOCOL_CMD_B_FRAME_ID, HIL_PROTOCOL_CMD_B_LENGTH, 1, 1)                       \
    X(HIL_PROTOCOL_CMD_C_FRAME_ID, HIL_PROTOCOL_CMD_C_LENGTH, 1, 1)                       \
    X(HIL_PROTOCOL_CMD_DUTY_A_FRAME_ID, HIL_PROTOCOL_CMD_DUTY_A_LENGTH, 1, 1)             \
    X(HIL_PROTOCOL_CMD_DUTY_B_FRAME_ID, HIL_PROTOCOL_CMD_DUTY_B_LENGTH, 1, 1)             \
    X(HIL_PROTOCOL_CMD_DUTY_C_FRAME_ID, HIL_PROTOCOL_CMD_DUTY_C_LENGTH, 1, 1)             \
    X(HIL_PROTOCOL_CMD_FD_FRAME_ID, HIL_PROTOCOL_CMD_FD_LENGTH, 1, 1)                     \
    X(HIL_PROTOCOL_CMD_DUTY_FD_FRAME_ID, HIL_PROTOCOL_CMD_DUTY_FD_LENGTH, 1, 1)           \
    X(HIL_PROTOCOL_SETPOINT_FRAME_ID, HIL_PROTOCOL_SETPOINT_LENGTH, 0, 0)                 \
    X(HIL_PROTOCOL_CONFIG_PARAM_FRAME_ID, HIL_PROTOCOL_CONFIG_PARAM_LENGTH, 0, 0)         \
    X(HIL_PROTOCOL_CONFIG_ACK_FRAME_ID, HIL_PROTOCOL_CONFIG_ACK_LENGTH, 1, 0)             \
    X(HIL_PROTOCOL_HEARTBEAT_HOST_FRAME_ID, HIL_PROTOCOL_HEARTBEAT_HOST_LENGTH, 0, 0)     \
    X(HIL_PROTOCOL_HEARTBEAT_TARGET_FRAME_ID, HIL_PROTOCOL_HEARTBEAT_TARGET_LENGTH, 1, 0)

#endif
