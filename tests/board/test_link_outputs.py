"""What the virtual board's outputs are when TIM1's are off (MOE = 0): the open bridge — before the first Command
too (the host applies the board's `first_duties` in period 0, not the zero vector) — or, when OSSI drives the
idle levels, their switching state; `outputs_off` tells the conformance probe which Commands stand for the gates
off; a bridge the idle levels drive in part is named, never guessed."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import pytest

from pmsm_hil.protocol.codec import FrameCodec, FrameDecoder
from pmsm_hil.protocol.messages import Command, Measurement
from pmsm_hil.sim_target.stm32g4.board_file import load_board
from pmsm_hil.sim_target.stm32g4.link import BoardLink
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import BDTR, CCER, CR2

TS = 50e-6
CODEC = FrameCodec("canfd")
WIRE = 1 / 65520
PSI_F, POLE_PAIRS, VDC = 0.1, 4, 48.0
OSSI = 1 << 10


def command(link: BoardLink, seq: int) -> Command:
    link.send(CODEC.encode(Measurement(seq=seq, i_a=1.0, i_b=-0.5, i_c=-0.5, theta_e=0.3, omega_m=50.0, vdc=VDC)))
    decoder = FrameDecoder(ordered=False)
    while (frame := link.poll()) is not None:
        msg = decoder.feed(frame)
        if isinstance(msg, Command):
            return msg
    raise AssertionError("no Command")


def open_bridge(theta_e: float, omega_m: float, ahead: float) -> list[float]:
    we = POLE_PAIRS * omega_m
    theta = theta_e + ahead * we * TS
    emf = [-we * PSI_F * math.sin(theta - k * 2 * math.pi / 3) for k in range(3)]
    mid = (max(emf) + min(emf)) / 2
    return [0.5 + (e - mid) / VDC for e in emf]


@pytest.fixture
def link(build_fw: Callable[..., Path]) -> BoardLink:
    return BoardLink(build_fw("pwm_adc"), load_board(), ts_s=TS, pole_pairs=POLE_PAIRS, psi_f_wb=PSI_F, vdc_v=VDC)


def test_the_first_period_is_the_open_bridge_while_the_outputs_are_off(link: BoardLink) -> None:
    link.tim1.trip_break()  # MOE = 0, as every firmware starts
    first = link.first_duties(1.0, 50.0)
    # the middle of period 0 is half a period after its start, where the plant's state was taken
    assert first == pytest.approx(open_bridge(1.0, 50.0, 0.5), abs=1e-12)
    assert len(first) == 3 and first[0] - first[1] != 0.0  # the back EMF's line voltage, not 0.5 everywhere


def test_the_first_period_is_the_compares_in_force_when_the_outputs_are_on(link: BoardLink) -> None:
    assert link.tim1.moe
    assert link.first_duties(1.0, 50.0) == tuple(link.tim1.duty(ch) for ch in link.desc.pwm_channels)


def test_a_command_with_the_gates_off_is_named_as_such(link: BoardLink) -> None:
    on = command(link, 1)
    assert on.duties and not link.outputs_off(1)
    link.tim1.trip_break()
    off = command(link, 2)
    assert off.duties == pytest.approx(open_bridge(0.3, 50.0, 1.5), abs=WIRE)
    assert link.outputs_off(2) and not link.outputs_off(1)


def test_idle_levels_driven_by_ossi_are_their_switching_state(link: BoardLink) -> None:
    tim = link.tim1
    tim.trip_break()
    tim.regs[BDTR] |= OSSI
    tim.regs[CR2] |= 0b10_10_10 << 8  # OIS1N, OIS2N, OIS3N: every lower switch on (CC1-3 and complements enabled)
    cmd = command(link, 5)
    assert (cmd.states, cmd.durations_ns, cmd.duties) == ((0,), (50_000,), ())  # the zero vector
    assert not link.outputs_off(5)
    tim.regs[CR2] = (tim.regs[CR2] & ~(0x3F << 8)) | 0b01_01_01 << 8  # OIS1..3: every upper switch on
    assert command(link, 6).states == (7,)
    assert link.first_duties(0.0, 100.0) == (1.0, 1.0, 1.0)
    tim.regs[BDTR] &= ~OSSI  # OSSI clear: the outputs are released whatever OISx says
    assert command(link, 7).duties and link.outputs_off(7)


def test_a_bridge_driven_in_part_is_named(link: BoardLink) -> None:
    tim = link.tim1
    tim.trip_break()
    tim.regs[BDTR] |= OSSI
    tim.regs[CCER] &= ~(0b0101 << 8)  # channel 3: both outputs disabled, the others driven low
    tim.regs[CR2] |= 0b10_10 << 8
    with pytest.raises(BoardError, match=r"TIM1 CR2 .*drive some legs and leave others open.*OISx/OISxN"):
        command(link, 1)
    tim.regs[CCER] |= 0b0101 << 8
    tim.regs[CR2] |= 0b11 << 12  # channel 3: OIS3 and OIS3N, both switches on
    with pytest.raises(BoardError, match=r"channel 3 turn both its switches on"):
        command(link, 2)
