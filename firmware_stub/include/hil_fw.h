/*
 * Portable C99 reference firmware for the PMSM HIL tester (umbrella header).
 */
#ifndef HIL_FW_H
#define HIL_FW_H

#include "hil_fw_types.h"
#include "hil_fw_config.h"
#include "hil_fw_transforms.h"
#include "hil_fw_speed_pi.h"
#include "hil_fw_inverter.h"
#include "hil_fw_mpcc.h"
#include "hil_fw_controllers.h"
#include "hil_fw_state.h"
#include "hil_fw_step.h"
#include "hil_fw_profile.h"

#endif
