/*
 * The part of the firmware API (hil_app.h) that the test firmwares of tests/firmware_board all write alike: any
 * controller is taken, there is no controller state to reset, and every Setpoint is accepted. A test firmware's one
 * C file includes it (`#include "../accept_all.h"`) after hil_app.h.
 */
#ifndef TESTS_FIRMWARE_BOARD_ACCEPT_ALL_H
#define TESTS_FIRMWARE_BOARD_ACCEPT_ALL_H

int hil_app_select(uint8_t controller_id)
{
    (void)controller_id;
    return HIL_APP_OK;
}

void hil_app_reset(void)
{
}

int hil_app_setpoint(uint8_t enable, uint8_t mode, float reference)
{
    (void)enable;
    (void)mode;
    (void)reference;
    return HIL_APP_OK;
}

#endif
