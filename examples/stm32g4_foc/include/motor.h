/*
 * The machine the firmware is tuned for: the niu2020 IPMSM (src/pmsm_hil/hil/presets/niu2020-ipmsm.toml, Niu et
 * al., IEEE Access 2020, Table 3) and the controller gains derived from it (README.md, "Gains"). A bus that
 * sends ConfigParams (the HIL host does) overrides the machine values and the speed gains at run time.
 */
#ifndef FW_MOTOR_H
#define FW_MOTOR_H

#define MOTOR_RS_OHM 4.5f
#define MOTOR_LD_H 0.012f
#define MOTOR_LQ_H 0.014f
#define MOTOR_PSI_F_WB 0.21f
#define MOTOR_POLE_PAIRS 3.0f
#define MOTOR_J_KGM2 0.0013f
#define MOTOR_VDC_NOMINAL_V 311.0f
#define MOTOR_RATED_SPEED_RPM 1500.0f
#define MOTOR_RATED_TORQUE_NM 7.0f

/* Current loop: bandwidth (rad/s) of the d/q PI loops; kp = wc*L, ki = wc*Rs (README.md, "Gains"). */
#ifndef FW_CURRENT_BW_RAD_S
#define FW_CURRENT_BW_RAD_S 3000.0f
#endif
/* Speed loop (1 kHz): crossover FW_SPEED_BW_RAD_S on the inertia, kp = J*ws, PI zero at ws/4 (README.md,
 * "Gains"). The host's speed_kp / speed_ki (tuned for a 10 kHz loop) are acknowledged but not used unless the
 * build defines FW_BUS_SPEED_GAINS. */
#ifndef FW_SPEED_BW_RAD_S
#define FW_SPEED_BW_RAD_S 150.0f
#endif
#ifndef FW_SPEED_KP
#define FW_SPEED_KP (MOTOR_J_KGM2 * FW_SPEED_BW_RAD_S) /* 0.195 N*m/(rad/s) */
#endif
#ifndef FW_SPEED_KI
#define FW_SPEED_KI (FW_SPEED_KP * FW_SPEED_BW_RAD_S / 4.0f) /* 7.3 N*m/rad */
#endif
/* Speed estimate: encoder PLL natural frequency (rad/s), critically damped. */
#ifndef FW_PLL_BW_RAD_S
#define FW_PLL_BW_RAD_S 1000.0f
#endif
/* Limits: torque 10/7 x rated, current 0.8 x the preset's trip level 30 A (as the HIL host sends them). */
#define FW_TORQUE_LIMIT_NM 10.0f
#define FW_CURRENT_LIMIT_A 24.0f

/* Without a bus (FW_NO_BUS, or no frame within FW_BUS_SILENT_MS of boot): this setpoint, enabled. */
#ifndef FW_DEFAULT_SPEED_RPM
#define FW_DEFAULT_SPEED_RPM 1500.0f
#endif
#ifndef FW_DEFAULT_TORQUE_INIT_NM
#define FW_DEFAULT_TORQUE_INIT_NM 7.0f /* speed-PI integrator preset: the expected load */
#endif
#ifndef FW_BUS_SILENT_MS
#define FW_BUS_SILENT_MS 100u
#endif

#endif /* FW_MOTOR_H */
