"""The C scheduler's event-driven models (Board.EVENT_DRIVEN, Peripheral.EVENT_DRIVEN: FDCAN1, the watchdogs,
CORDIC): asked only when their next event is due, after an access to them, a core clock change or a run-side input,
with the reference's records — a frame FDCAN1 receives between two of its events reaches the firmware at the same
cycle, a watchdog that expires resets the board at the same cycle. That the example and test firmwares give the
reference's records bit for bit is checked with the board's other fast paths in tests/board/test_native_exc.py."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import pytest

from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.messages import ConfigParam, Measurement, Setpoint
from pmsm_hil.sim_target.stm32g4.board import Board
from pmsm_hil.sim_target.stm32g4.board_file import load_board
from pmsm_hil.sim_target.stm32g4.link import BoardLink
from pmsm_hil.sim_target.stm32g4.part import PARTS
from pmsm_hil.sim_target.stm32g4.peripherals.fdcan import Fdcan
from pmsm_hil.sim_target.stm32g4.peripherals.iwdg import Iwdg
from pmsm_hil.sim_target.stm32g4.peripherals.watchdog import WatchdogResetError
from pmsm_hil.sim_target.stm32g4.peripherals.wwdg import Wwdg
from tests.board.test_native_exc import EXAMPLE_BOARD, TS, example

FDCAN1_IT0 = 16 + 21
#: the schedulers compared: (NATIVE_CORE, EVENT_DRIVEN)
SCHEDULERS = {"event_driven": (True, True), "every_step": (True, False), "python": (False, False)}


def counting_advance(monkeypatch: pytest.MonkeyPatch, cls: type[Any], calls: list[int]) -> None:
    """Count the calls of `cls.advance` into `calls`."""
    advance = cls.advance

    def counted(self: Any, now: int) -> None:
        calls.append(now)
        advance(self, now)

    monkeypatch.setattr(cls, "advance", counted)


def bus_records(scheduler: str, monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    """The example firmware over 120 periods with the host's ConfigParam and Setpoint frames on its bus at period
    30: every frame FDCAN1 sent with its end cycle, the exception statistics, the board's time."""
    native_core, event_driven = SCHEDULERS[scheduler]
    monkeypatch.setattr(Board, "NATIVE_CORE", native_core)
    monkeypatch.setattr(Board, "EVENT_DRIVEN", event_driven)
    sent: list[tuple[float, int, bytes]] = []
    take = Fdcan.take_transmitted

    def taken(self: Fdcan) -> list[can.Message]:
        frames = take(self)
        sent.extend((float(m.timestamp), int(m.arbitration_id), bytes(m.data)) for m in frames)
        return frames

    monkeypatch.setattr(Fdcan, "take_transmitted", taken)
    touched_on_delivery: list[bool] = []
    deliver = Fdcan.deliver

    def delivered(self: Fdcan, frame: can.Message, now: int) -> None:
        deliver(self, frame, now)
        board = self.bus
        assert isinstance(board, Board)
        if board._native_core:  # the cached next event is asked again at the scheduler's next step
            touched_on_delivery.append(bool(board._core.models[board._slot[self]].touched))

    monkeypatch.setattr(Fdcan, "deliver", delivered)
    advances: list[int] = []
    counting_advance(monkeypatch, Fdcan, advances)
    link = BoardLink(example(), load_board(EXAMPLE_BOARD), ts_s=TS, pole_pairs=4)
    codec = FrameCodec("canfd")
    answers: list[bytes] = []
    for k in range(120):
        th = (2 * math.pi * 50.0 * k * TS) % (2 * math.pi)
        m = Measurement(seq=k, i_a=10 * math.cos(th), i_b=10 * math.cos(th - 2.094), i_c=10 * math.cos(th + 2.094),
                        theta_e=th, omega_m=78.5, vdc=48.0)
        if k == 30:
            link.send([*codec.encode(ConfigParam(param_id=11, value=7.0)),
                       *codec.encode(Setpoint(enable=True, mode=0, reference=100.0, controller_id=255))])
            while (frame := link.poll()) is not None:
                answers.append(bytes(frame.data))
        link.send(codec.encode(m))
        while (frame := link.poll()) is not None:
            answers.append(bytes(frame.data))
    board = link.board
    monkeypatch.undo()  # the wrappers above off before the next run
    return {"sent": sent, "answers": answers, "now": board.now, "sleep": board.sleep_cycles,
            "handlers": {e: (s.entries, s.cycles, s.latency) for e, s in board.isr.items()},
            "advances": len(advances), "touched": touched_on_delivery}


def test_a_frame_fdcan1_receives_between_its_events_reaches_the_firmware_at_the_reference_cycle(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The host's frames are delivered to FDCAN1 while its next event is far ahead (nothing on the bus): the
    delivery marks it touched, and the firmware's receive interrupt, its answer and every record are those of the
    schedulers that ask FDCAN1 at every step — which call its `advance` many times more."""
    runs = {name: bus_records(name, monkeypatch) for name in SCHEDULERS}
    reference = runs["python"]
    assert reference["handlers"][FDCAN1_IT0][0] >= 1  # the firmware took the frames in its receive interrupt
    assert reference["sent"] and reference["sent"][0][1] == 0x211  # its ConfigAck on the bus
    for name, out in runs.items():
        for key in ("sent", "answers", "now", "sleep", "handlers"):
            assert out[key] == reference[key], f"{key} differs between {name} and the Python scheduler"
    assert runs["event_driven"]["touched"] and all(runs["event_driven"]["touched"])
    assert 3 * runs["event_driven"]["advances"] < runs["every_step"]["advances"]


@pytest.mark.parametrize(("defines", "model", "name"), [((), Wwdg, "WWDG"), (("USE_IWDG",), Iwdg, "IWDG")],
                         ids=["wwdg", "iwdg"])
def test_a_watchdog_that_expires_resets_the_board_at_the_reference_cycle(
        defines: tuple[str, ...], model: type[Any], name: str, build_fw: Callable[..., Path],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """tests/board/fw/periph.c leaves its watchdog unrefreshed: the reset (and the WWDG's early wakeup interrupt
    before it) comes at the cycle of the schedulers that ask the watchdog at every step (the firmware sleeps in WFI
    meanwhile: few steps; the event-driven scheduler advances the watchdog at no more of them)."""
    elf = build_fw("periph", *defines)
    seen: dict[str, tuple[Any, ...]] = {}
    advances: dict[str, list[int]] = {}
    for scheduler, (native_core, event_driven) in SCHEDULERS.items():
        monkeypatch.setattr(Board, "NATIVE_CORE", native_core)
        monkeypatch.setattr(Board, "EVENT_DRIVEN", event_driven)
        calls = advances[scheduler] = []
        counting_advance(monkeypatch, model, calls)
        board = Board(PARTS["stm32g474"], elf)
        if native_core:
            assert board._core.models[board._slot[board.peripherals[name]]].event_driven == event_driven
        with pytest.raises(WatchdogResetError, match=f"watchdog reset by {name}") as ended:
            board.run_until(16_000_000 // 4)
        monkeypatch.undo()
        seen[scheduler] = (ended.value.cycle, str(ended.value), board.now, board.sleep_cycles,
                           {e: (s.entries, s.cycles, s.latency) for e, s in board.isr.items()},
                           bytes(board.read_memory(0x2000_0000, board.part.sram_size)))
    assert seen["event_driven"] == seen["python"] and seen["every_step"] == seen["python"]
    assert 0 < len(advances["event_driven"]) <= len(advances["every_step"])


@pytest.mark.parametrize("event_driven", [True, False], ids=["event_driven", "every_step"])
def test_the_example_board_calls_no_python_model_between_its_events(event_driven: bool,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """The example firmware's periods, one run_until each: with the event-driven models cached and the resting
    ones (the encoder timer TIM3, TIM4, EXTI without edges) left resting across calls and the current loop's reads
    of TIM3, the C core calls none of the Python models' batches; asking at every step calls them several times a
    period."""
    monkeypatch.setattr(Board, "EVENT_DRIVEN", event_driven)
    calls: list[str] = []
    for name in ("_py_advance", "_py_next_event", "_py_quiet", "_py_next_each"):
        method = getattr(Board, name)

        def counted(self: Board, *args: Any, name: str = name, method: Any = method) -> Any:
            calls.append(name)
            return method(self, *args)

        monkeypatch.setattr(Board, name, counted)
    link = BoardLink(example(), load_board(EXAMPLE_BOARD), ts_s=TS, pole_pairs=4)
    board = link.board
    assert board._core.models[board._slot[board.peripherals["TIM3"]]].resting
    calls.clear()
    for _ in range(50):
        board.run_until(board.now + link.period_cycles)
    if event_driven:
        assert calls == []
    else:
        assert len(calls) > 4 * 50
