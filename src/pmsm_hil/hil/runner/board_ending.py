"""How a run on the virtual STM32G4 board (`--target stm32g4:FW.elf`) ended when the firmware stopped the board:
a fault (the report names pc, lr and CFSR decoded, as a `qemu:` target's) or an access the board does not model
(the register, address and function), in a period or in its start-up (raised at the first Measurement). Both end
the run as a safety stop (exit 3) with that one line as the reason; the board raised them from inside the link, so
the loop saw them as its link's error."""

from __future__ import annotations

from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.loop_outcome import LoopOutcome
from pmsm_hil.sim_target.stm32g4.fault import BoardFaultError
from pmsm_hil.sim_target.stm32g4.frame_link import FrameBoardLink
from pmsm_hil.sim_target.stm32g4.link import BoardLink
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError


def judge_board(link: BoardLink | FrameBoardLink, out: LoopOutcome) -> None:
    """Rewrite the ending `out` in place when the board stopped the firmware; other endings stay."""
    error = out.error
    if not isinstance(error, BoardError) or out.end_code == EndCode.INTERRUPTED:
        return
    when = "in its start-up, before the first period" if error is link.boot_error else f"in period {link.periods}"
    if isinstance(error, BoardFaultError):
        reason = f"target {error.description} {when}: the virtual board stopped the MCU"
    else:
        reason = f"target stopped {when}: {error}"
    out.error = None
    out.end_code = int(EndCode.SAFETY_STOP)
    out.end_reason = f"{reason}; inverter put in the safe state (zero vector)"
    out.safe_state = True
