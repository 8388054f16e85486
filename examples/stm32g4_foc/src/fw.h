/* What the firmware's files share: the run state, the control entry points and the bus/console drivers. */
#ifndef FW_H
#define FW_H

#include <stdint.h>

/* Setpoint as the bus (or the compile-time default) gives it. */
typedef struct {
    uint8_t enable;
    uint8_t mode;      /* 0 speed [rad/s mechanical], 1 torque [N*m] */
    float reference;
    uint8_t controller_id;
} fw_setpoint_t;

void SystemClock_Config(void);
/* Stop the drive at once (MOE off, gate enable low), remember the exception and its CFSR, and halt. */
void fw_fault_stop(uint32_t exception) __attribute__((noreturn));

/* control (main.c) */
int fw_config(uint8_t param_id, float value);            /* 0 ok, else rejected */
int fw_apply_setpoint(const fw_setpoint_t *sp);           /* 0 ok, else FaultTarget status (5 or 6) */
uint8_t fw_running(void);

/* console (console.c): USART2, blocking writes */
void console_init(uint32_t pclk_hz, uint32_t baud);
void console_write(const char *s);
void console_write_u32(uint32_t v);

/* bus (can_link.c): FDCAN1 with the project's DBC */
int can_init(void);                 /* 0 ok, -1 the controller did not enter/leave initialisation */
uint32_t can_frames_received(void);
void can_send_heartbeat(uint8_t state, uint8_t counter);

#endif /* FW_H */
