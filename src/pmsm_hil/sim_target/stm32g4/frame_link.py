"""A firmware-API image on the virtual board (`--target stm32g4:FW.elf` for an ELF built by `hil fw build --board
stm32g474 --src DIR`): the firmware's board layer (firmware_stub/boards/stm32g474/) carries the protocol's frames on
FDCAN1, so the host's end of the link is the board's CAN bus, as it is on a real bench with a CAN FD adapter.

Every host frame goes on the bus one after the other: it is delivered to FDCAN1 at the end of its bus time (the
firmware's bit rates, `Fdcan.frame_cycles`) while the firmware runs. Measurement k starts its transmission one
control period (--ts) after Measurement k-1 (or when the bus is free), as the host of a real-time bench sends them;
the board then runs until the firmware's Command has left the bus, at most the period plus LATE_PERIODS periods
(a Command that ends after the period would be late on a real bench: counted in `board_late_replies`). Other frames
(configuration, Setpoints, heartbeats) run the firmware for a period; when it has not answered yet, `poll` runs up
to IDLE_PERIODS more. The firmware's own exec_time_ns (its DWT cycle counter around hil_app_step) is in each
Command; `board_turnaround_cycles` is the MCU's share of a period: from the Measurement's arrival to the start of
its Command on the bus (the FDCAN interrupt, the target core, the step, the frame encoding and the TX request).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import can
import numpy as np

from pmsm_hil.protocol.codec import FrameDecoder, Profile
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.messages import Command, Measurement
from pmsm_hil.sim_target.qemu import stats
from pmsm_hil.sim_target.stm32g4.board import Board
from pmsm_hil.sim_target.stm32g4.board_file import BoardDescription
from pmsm_hil.sim_target.stm32g4.link_base import IDLE_PERIODS, STARTUP_LIMIT_S, STARTUP_STEP, BoardLinkBase
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.fdcan import FDOE, Fdcan
from pmsm_hil.sim_target.stm32g4.peripherals.fdcan import INIT as FDCAN_INIT

#: periods past its own that a Measurement's Command may take before the board stops waiting
LATE_PERIODS = 20
#: the symbol that marks an image built on the firmware API's board layer (the portable target core)
CORE_SYMBOL = "hil_core_rx"


def is_core_image(board_or_elf: Board | str | Path) -> bool:
    """Whether an ELF is built on the firmware API's board layer (it links the target core), not a bare-metal
    firmware that meets the plant through TIM1 and the ADCs."""
    from pmsm_hil.sim_target.elf import elf_symbols

    if isinstance(board_or_elf, Board):
        return board_or_elf.symbol(CORE_SYMBOL) is not None
    return CORE_SYMBOL in elf_symbols(Path(board_or_elf))


class FrameBoardLink(BoardLinkBase):
    """The host's link to a firmware-API image on the virtual board, over its FDCAN1 (the Link protocol)."""

    def __init__(self, elf: str | Path, desc: BoardDescription, *, ts_s: float, skip_periods: int = 0,
                 console: Any = None, can_bitrates: tuple[int | None, int | None] = (None, None)) -> None:
        super().__init__(elf, desc, skip_periods=skip_periods, console=console)
        fdcan = self.board.peripherals.get("FDCAN1")
        if not isinstance(fdcan, Fdcan):
            raise BoardError(f"stm32g4 target: part {desc.part.name} has no FDCAN1 model")
        self.fdcan = fdcan
        fdcan.link_bitrates = can_bitrates  # checked against the firmware's bit timing when it joins the bus
        self._host = FrameDecoder(ordered=False)
        self._replies = FrameDecoder(ordered=False)
        self.late_replies = 0
        self.missing_replies = 0
        self.turnaround_cycles: list[int] = []
        self.sleep_cycles: list[int] = []
        self.elapsed_cycles: list[int] = []  # board time per control period (longer than --ts when late)
        self._command_start = 0
        # boot_error stays None: a start-up that fails raises from this constructor (`_start`), before any period
        self._start()
        self.fd = self.profile == "canfd"
        self.hclk_hz = self.board.hclk_hz
        self.period_cycles = max(1, round(ts_s * self.hclk_hz))
        self._bus_free = self.board.now
        self._next_slot = self.board.now

    def _start(self) -> None:
        """Run the firmware's start-up until FDCAN1 leaves initialisation (its board layer is then serving)."""
        board = self.board
        self._run_startup(lambda: not self.fdcan.cccr & FDCAN_INIT,
                          lambda: "stm32g4 target: the firmware did not take FDCAN1 out of initialisation within "
                                  f"{STARTUP_LIMIT_S:g} s of its start-up (at {board.describe_pc()}); an image built "
                                  "with `hil fw build --board stm32g474 --src DIR` does so in its main()")
        board.run_until(board.now + STARTUP_STEP)  # the core initialised, the main loop asleep in WFI

    @property
    def profile(self) -> Profile:
        """The frame layouts the firmware takes: "canfd" when it enabled FD operation (CCCR.FDOE), else "can"."""
        return "canfd" if self.fdcan.cccr & FDOE else "can"

    # --- the bus ------------------------------------------------------------------------------------------------

    def _on_bus(self, frame: Frame, not_before: int) -> tuple[int, int]:
        """Send one host frame: it starts when the bus is free (and not before `not_before`), the firmware runs
        meanwhile, and FDCAN1 receives it at its end; returns the cycles of its start and end."""
        msg = _can(frame)
        start = max(self._bus_free, not_before, self.board.now)
        end = start + self.fdcan.frame_cycles(msg)
        self.board.run_until(end)
        self.fdcan.deliver(msg, self.board.now)
        self._bus_free = end
        return start, end

    def _collect(self) -> Command | None:
        """The frames the firmware sent, into the host's queue; the Command among them, if one completed."""
        command = None
        for m in self.fdcan.take_transmitted():
            frame = Frame(int(m.arbitration_id), bytes(m.data), bool(m.is_fd))
            self._rx.append(frame)
            end = round(float(m.timestamp) * self.board.sysclk_hz)
            self._bus_free = max(self._bus_free, end)
            msg = self._replies.feed(frame)
            if isinstance(msg, Command):
                command = msg
                self._command_start = end - self.fdcan.frame_cycles(m)
        return command

    def _measurement(self, frames: list[Frame]) -> None:
        """One control period: the Measurement's frames on the bus from its slot (one period after the previous
        one's), the firmware until its Command has left the bus, then to the next slot."""
        slot = self._next_slot
        sleep0, t0 = self.board.sleep_cycles, self.board.now
        first = arrival = slot
        for i, frame in enumerate(frames):
            start, arrival = self._on_bus(frame, slot)
            if i == 0:
                first = start
        self._next_slot = first + self.period_cycles
        deadline = self._next_slot
        last = deadline + LATE_PERIODS * self.period_cycles
        command = self._collect()
        while command is None and self.board.now < last:
            self.board.run_until(min(self.board.now + self.period_cycles // 8 + 1, last))
            command = self._collect()
        if command is None:
            self.missing_replies += 1
        else:
            self.turnaround_cycles.append(self._command_start - arrival)
            if self._bus_free > deadline:
                self.late_replies += 1
        if self.board.now < deadline:
            self.board.run_until(deadline)
        self.sleep_cycles.append(self.board.sleep_cycles - sleep0)
        self.elapsed_cycles.append(self.board.now - t0)
        self.periods += 1

    def _idle_period(self) -> None:
        """One period of the firmware with no Measurement (it answers configuration, Setpoints, heartbeats)."""
        self.board.run_until(self.board.now + self.period_cycles)
        self._collect()
        self._next_slot = max(self._next_slot, self.board.now)

    # --- Link -----------------------------------------------------------------------------------------------

    def send(self, frames: Sequence[Frame]) -> None:
        t0 = time.perf_counter()
        pending: list[Frame] = []
        periods = 0
        for frame in frames:
            self.stats.frames_tx += 1
            pending.append(frame)
            if isinstance(self._host.feed(frame), Measurement):
                self._idle_left = 0
                self._measurement(pending)
                periods += 1
                pending = []
        for frame in pending:  # frames after the last Measurement: on the bus now
            self._on_bus(frame, self.board.now)
        if pending and not periods:  # no Measurement: the firmware gets a period to answer, more in `poll`
            self._idle_period()
            self._idle_left = IDLE_PERIODS
        elif pending:
            self._collect()
        self.wall_s += time.perf_counter() - t0

    def _poll_idle_period(self) -> None:
        """Up to IDLE_PERIODS of them, until the firmware has answered."""
        self._idle_left -= 1
        self.idle_periods += 1
        self._idle_period()
        if self._rx:
            self._idle_left = 0

    # --- what the run says ------------------------------------------------------------------------------------

    def metrics(self) -> dict[str, Any]:
        """The board's metrics over the metrics window (the periods from `skip_periods`)."""
        window = slice(self.skip_periods, None)
        turn = np.asarray(self.turnaround_cycles[window], dtype=float)
        sleep = np.asarray(self.sleep_cycles[window], dtype=float)
        elapsed = np.asarray(self.elapsed_cycles[window], dtype=float)
        us = 1e6 / self.hclk_hz
        out: dict[str, Any] = {"mcu_clock_hz": float(self.hclk_hz), "board": self.desc.name,
                               "board_link": "fdcan1", "board_idle_periods": self.idle_periods,
                               "board_late_replies": self.late_replies,
                               "board_missing_replies": self.missing_replies,
                               "board_can_bitrates": list(self.fdcan_bitrates())}
        if len(turn):
            out["board_turnaround_cycles"] = stats(turn)
            out["board_turnaround_us"] = stats(turn * us)
        if len(sleep) and elapsed.sum() > 0:
            out["board_cpu_load"] = float(1.0 - sleep.sum() / elapsed.sum())
        return out

    def fdcan_bitrates(self) -> tuple[int, int]:
        """(nominal, data) bit rates the firmware configured [bit/s], from FDCAN1's bus time of frames that differ
        by 8 nominal-rate bytes (classic 8 and 0 bytes) and by 16 data-rate bytes (FD 64 and 48 bytes)."""
        cycles = self.fdcan.frame_cycles
        nominal = cycles(_can(Frame(0x100, bytes(8), False))) - cycles(_can(Frame(0x100, b"", False)))
        data = cycles(_can(Frame(0x108, bytes(64), True))) - cycles(_can(Frame(0x108, bytes(48), True)))
        hz = self.board.sysclk_hz
        return (round(64 * hz / nominal) if nominal > 0 else 0, round(128 * hz / data) if data > 0 else 0)


def _can(frame: Frame) -> can.Message:
    return can.Message(arbitration_id=frame.arbitration_id, data=frame.data, is_fd=frame.is_fd,
                       bitrate_switch=frame.is_fd, is_extended_id=frame.arbitration_id > 0x7FF)
