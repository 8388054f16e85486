"""What the host's two links to the virtual board share (link.py: register-level firmware; frame_link.py: a
firmware-API image over FDCAN1): the board, the queue of frames for the host, `poll` / `recv` / `close` with the
idle periods a link runs while the firmware still has to answer, and the start-up run until the firmware is ready.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links.stats import LinkStats
from pmsm_hil.sim_target.stm32g4.board import Board
from pmsm_hil.sim_target.stm32g4.board_file import BoardDescription
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError

#: emulated time the firmware's start-up may take before it is ready (TIM1 counts, FDCAN1 on the bus) [s]
STARTUP_LIMIT_S = 2.0
#: idle periods run for frames that reach the firmware outside a control period, until it answers
IDLE_PERIODS = 20
#: the start-up runs in slices of this many cycles (1 ms at 170 MHz)
STARTUP_STEP = 170_000


class BoardLinkBase:
    """The Link protocol's `poll` / `recv` / `close` over the board's queue of frames for the host; a subclass
    says when a poll runs an idle period of the firmware (`_idle_due`, `_poll_idle_period`)."""

    #: the firmware runs only when the host polls or sends (virtual time): TargetClient.configure resends by that
    runs_when_polled = True

    def __init__(self, elf: str | Path, desc: BoardDescription, *, skip_periods: int, console: Any) -> None:
        self.stats = LinkStats()
        self.fd = True
        self.desc = desc
        self.skip_periods = skip_periods
        self.board = Board(desc.part, elf, console=console, hse_hz=desc.hse_hz)
        self._rx: deque[Frame] = deque()
        self._idle_left = 0  # idle periods still to run for frames delivered outside a period
        self.periods = 0
        self.idle_periods = 0
        self.closed = False
        self.wall_s = 0.0
        #: why the firmware stopped the board in its start-up (None: it did not)
        self.boot_error: BoardError | None = None

    def _run_startup(self, ready: Callable[[], bool], late: Callable[[], str]) -> None:
        """Run the firmware until `ready()`; BoardError with `late()` (called then) past STARTUP_LIMIT_S of
        emulated time."""
        board = self.board
        limit = round(STARTUP_LIMIT_S * 170e6)
        while not ready():
            if board.now > limit:
                raise BoardError(late())
            board.run_until(board.now + STARTUP_STEP)

    def _idle_due(self) -> bool:
        """A poll that finds no frame runs an idle period of the firmware now."""
        return self._idle_left > 0

    def _poll_idle_period(self) -> None:
        """The idle period a poll runs (`_idle_due`)."""
        raise NotImplementedError

    def pending(self) -> bool:
        """Whether `poll` could return a frame or run the firmware now (False: it would return None and do
        nothing)."""
        return bool(self._rx) or self._idle_due()

    def requeue(self, frames: list[Frame]) -> None:
        """Frames for the host taken from the queue but not delivered (a C link's, after its run) back at its
        front, in their order."""
        self._rx.extendleft(reversed(frames))

    def poll(self) -> Frame | None:
        """The board's next frame for the host, after an idle period of the firmware when one is due; None."""
        if not self._rx and self._idle_due():
            self._poll_idle_period()
        if self._rx:
            self.stats.frames_rx += 1
            return self._rx.popleft()
        return None

    def recv(self, timeout_s: float) -> Frame | None:
        """As `poll`: the board answers in this process, nothing arrives by waiting."""
        return self.poll()

    def close(self) -> None:
        """Nothing to release (idempotent)."""
        self.closed = True
