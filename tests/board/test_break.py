"""TIM1's break input driven by the board's overcurrent protection ([break_input] in the board description): a
phase current above its level puts BKIN at its active level, the break clears MOE (the outputs go to their idle
state: the open bridge), sets BIF and runs the firmware's break interrupt (fw/pwm_adc.c, BREAK); MOE stays cleared
while the current stays high, and a firmware that sets the wrong polarity never gets its outputs on."""

from __future__ import annotations

import dataclasses
import struct
from collections.abc import Callable
from pathlib import Path

import pytest

from pmsm_hil.protocol.codec import FrameCodec, FrameDecoder
from pmsm_hil.protocol.messages import Command, Measurement
from pmsm_hil.sim_target.stm32g4.board_file import BOARDS_DIR, DEFAULT_BOARD, BoardDescription, load_board
from pmsm_hil.sim_target.stm32g4.link import BoardLink
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import BDTR, BIF, BKE, BKP, DIER, MOE, SR

#: every test with TIM1 and the ADCs in C and with their Python reference
pytestmark = pytest.mark.usefixtures("tim_adc_models")

TS = 50e-6
CODEC = FrameCodec("canfd")
LIMIT_A = 30.0


def board(active_low: bool = True) -> BoardDescription:
    return dataclasses.replace(load_board(), break_overcurrent_a=LIMIT_A, break_active_low=active_low)


def command(link: BoardLink, seq: int, current: float) -> Command:
    link.send(CODEC.encode(Measurement(seq=seq, i_a=current, i_b=-current / 2, i_c=-current / 2, theta_e=0.3,
                                       omega_m=50.0, vdc=48.0)))
    decoder = FrameDecoder(ordered=False)
    while (frame := link.poll()) is not None:
        msg = decoder.feed(frame)
        if isinstance(msg, Command):
            return msg
    raise AssertionError("no Command")


def u32(link: BoardLink, name: str) -> int:
    address = link.board.symbol(name)
    assert address is not None, name
    return int(struct.unpack("<I", link.board.read_memory(address, 4))[0])


def test_an_overcurrent_trips_the_break_and_opens_the_bridge(build_fw: Callable[..., Path]) -> None:
    link = BoardLink(build_fw("pwm_adc", "BREAK"), board(), ts_s=TS, pole_pairs=4, psi_f_wb=0.1, vdc_v=48.0)
    tim = link.tim1
    for seq in range(3):  # below the limit: the outputs switch
        cmd = command(link, seq, 10.0)
        assert cmd.duties and not link.outputs_off(seq)
    assert tim.moe and tim.break_trips == 0 and u32(link, "break_count") == 0
    over = command(link, 3, 45.0)  # the plant's overcurrent at this period's sample
    assert not tim.moe and tim.break_trips == 1
    assert link.outputs_off(3) and over.duties is not None and over.duties != ()  # the open bridge
    assert u32(link, "break_count") == 1 and u32(link, "break_sr") & BIF
    assert tim.regs[SR] & BIF  # the ISR's clear does not hold while BKIN stays active
    for seq in range(4, 7):  # the current falls again: without AOE the outputs stay off
        command(link, seq, 5.0)
        assert link.outputs_off(seq) and not tim.moe
    assert tim.break_trips == 1 and u32(link, "break_count") == 1
    assert link.metrics()["board_break_trips"] == 1


def test_the_firmware_cannot_set_moe_while_the_break_is_active(build_fw: Callable[..., Path]) -> None:
    link = BoardLink(build_fw("pwm_adc", "BREAK"), board(), ts_s=TS, pole_pairs=4)
    tim = link.tim1
    command(link, 0, 50.0)
    assert not tim.moe
    tim.write(BDTR, 4, tim.regs[BDTR] | MOE, link.board.now)
    assert not tim.moe
    command(link, 1, 0.0)  # the overcurrent is gone: MOE can be set again
    tim.write(BDTR, 4, tim.regs[BDTR] | MOE, link.board.now)
    assert tim.moe


def test_a_break_polarity_opposite_to_the_boards_holds_the_outputs_off(build_fw: Callable[..., Path]) -> None:
    # the board's comparator output is active high, the firmware selected BKP = 0 (active low): BRK is active
    # whenever the current is normal, so the firmware's MOE never takes
    link = BoardLink(build_fw("pwm_adc", "BREAK"), board(active_low=False), ts_s=TS, pole_pairs=4)
    tim = link.tim1
    assert tim.regs[BDTR] & BKE and not tim.regs[BDTR] & BKP
    command(link, 0, 1.0)
    assert not tim.moe and tim.break_trips >= 1 and link.outputs_off(0)


def test_the_break_interrupt_follows_bif_and_bie(build_fw: Callable[..., Path]) -> None:
    link = BoardLink(build_fw("pwm_adc", "BREAK"), board(), ts_s=TS, pole_pairs=4)
    tim = link.tim1
    assert tim.regs[DIER] & (1 << 7)
    command(link, 0, 100.0)
    assert u32(link, "break_count") == 1 and not tim.regs[DIER] & (1 << 7)  # the handler disabled BIE


def test_without_a_break_input_the_board_never_trips(build_fw: Callable[..., Path]) -> None:
    link = BoardLink(build_fw("pwm_adc", "BREAK"), load_board(), ts_s=TS, pole_pairs=4)
    command(link, 0, 500.0)
    assert link.tim1.moe and link.tim1.break_trips == 0


def test_a_bad_break_input_table_names_the_field(tmp_path: Path) -> None:
    text = (BOARDS_DIR / f"{DEFAULT_BOARD}.toml").read_text()
    bad = tmp_path / "b.toml"
    bad.write_text(text + "\n[break_input]\novercurrent_a = -3.0\n")
    with pytest.raises(BoardError, match="overcurrent_a"):
        load_board(bad)
    bad.write_text(text + "\n[break_input]\novercurrent_a = 30.0\nactive_low = 1\n")
    with pytest.raises(BoardError, match="active_low"):
        load_board(bad)
    good = tmp_path / "g.toml"
    good.write_text(text + "\n[break_input]\novercurrent_a = 30\n")
    desc = load_board(good)
    assert desc.break_overcurrent_a == 30.0 and desc.break_active_low
