"""Hall sensors on GPIO inputs: the levels of the three pins a board description names (`[hall]`) follow the
rotor's electrical angle at the cycle the firmware reads them, and the GPIO ports ask here when a pin changes next
so that EXTI takes each edge at its instant.

The angle is a trajectory the run side gives: `trajectory(now)` -> (electrical angle [rad] at cycle `now`,
electrical speed [rad per cycle]), linear between the run side's updates (one per control period).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from pmsm_hil.sim_target.stm32g4.board_file import HallInputs
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardBus, BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.gpio import GpioPort
from pmsm_hil.sim_target.stm32g4.peripherals.tim_gp import GeneralTimer

TWO_PI = 2 * math.pi
#: cycles looked past an edge computed in floating point before giving up on it (rounding at the crossing)
EDGE_SLACK = 4

Trajectory = Callable[[int], tuple[float, float]]


class HallSensors:
    """The three sensors of `desc` on the angle `trajectory`; a GPIO port reads its pins through `levels` and
    `next_change` (the InputDriver of peripherals/gpio.py)."""

    def __init__(self, desc: HallInputs, trajectory: Trajectory) -> None:
        self.desc = desc
        self.trajectory = trajectory
        step = math.radians(desc.spacing_deg)
        #: per sensor: (port letter, pin, electrical position [rad])
        self.sensors = tuple((port, pin, desc.offset_rad + k * step) for k, (port, pin) in enumerate(desc.pins))

    def port_mask(self, port: str) -> int:
        """The pins of GPIO`port` that carry a sensor."""
        return sum(1 << pin for p, pin, _ in self.sensors if p == port)

    @staticmethod
    def _high(theta: float, position: float) -> bool:
        return (theta - position) % TWO_PI < math.pi

    def code(self, now: int) -> int:
        """The sensors' levels at cycle `now` as A | B << 1 | C << 2."""
        theta = self.trajectory(now)[0]
        return sum(1 << k for k, (_, _, pos) in enumerate(self.sensors) if self._high(theta, pos))

    def levels(self, port: str, now: int) -> int:
        """The levels of GPIO`port`'s sensor pins at cycle `now` (bit per pin)."""
        theta = self.trajectory(now)[0]
        return sum(1 << pin for p, pin, pos in self.sensors if p == port and self._high(theta, pos))

    def next_change(self, port: str, mask: int, now: int) -> int | None:
        """The first cycle after `now` at which a sensor pin of GPIO`port` in `mask` changes level on the current
        trajectory (None when the rotor stands)."""
        theta, rate = self.trajectory(now)
        if rate == 0.0 or not math.isfinite(rate):
            return None
        best: int | None = None
        for p, pin, pos in self.sensors:
            if p != port or not mask >> pin & 1:
                continue
            phase = (theta - pos) % TWO_PI
            if rate > 0:  # the level changes on reaching π or 2π
                gap = (math.pi if phase < math.pi else TWO_PI) - phase
            else:  # on falling below 0 or below π
                gap = phase if phase < math.pi else phase - math.pi
            at = self._crossing(now, gap / abs(rate), theta, pos)
            if best is None or at < best:
                best = at
        return best

    def next_edge(self, now: int) -> int | None:
        """The first cycle after `now` at which any sensor changes level (a timer's hall interface)."""
        edges = [self.next_change(port, self.port_mask(port), now) for port in sorted({p for p, _, _ in self.sensors})]
        due = [at for at in edges if at is not None]
        return min(due) if due else None

    def _crossing(self, now: int, cycles: float, theta: float, position: float) -> int:
        """The first whole cycle after `now` at which the sensor at `position` reads otherwise than at `now`,
        `cycles` the exact distance in floating point."""
        start = self._high(theta, position)
        at = max(now + 1, math.ceil(now + cycles))
        for candidate in range(max(now + 1, at - 1), at + EDGE_SLACK):
            if self._high(self.trajectory(candidate)[0], position) != start:
                return candidate
        return at + EDGE_SLACK


def attach_halls(board: BoardBus, desc: HallInputs, trajectory: Trajectory) -> HallSensors:
    """Wire the hall sensors of `desc` into the GPIO ports of `board` (their pins then follow `trajectory`)."""
    halls = HallSensors(desc, trajectory)
    for letter in sorted({port for port, _ in desc.pins}):
        port = board.peripheral(f"GPIO{letter}")
        if not isinstance(port, GpioPort):
            raise BoardError(f"board [hall]: GPIO{letter} is not modelled on this part")
        port.drive(halls, halls.port_mask(letter))
    if desc.timer is not None:
        timer = board.peripheral(desc.timer)
        if not isinstance(timer, GeneralTimer):
            raise BoardError(f"board [hall]: 'timer' = {desc.timer!r} is not modelled on this part")
        timer.hall_inputs = halls
        timer.inputs_changed()  # it no longer rests (GeneralTimer.quiet)
    return halls
