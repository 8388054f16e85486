"""TIM1 (centre-aligned PWM, preload, OC4REF as TRGO2), ADC1 injected conversions triggered by it with their JEOS
interrupt, and TIM3 in encoder mode, on a small interrupt-driven firmware (fw/pwm_adc.c)."""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path

import pytest

from pmsm_hil.sim_target.stm32g4.board import Board
from pmsm_hil.sim_target.stm32g4.part import IRQ, PARTS
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import Tim1

#: every test with TIM1 and the ADCs in C and with their Python reference
pytestmark = pytest.mark.usefixtures("tim_adc_models")

HCLK = 170_000_000
ARR = 4250
ADC_IRQ = 16 + IRQ["ADC1_2"]


def u32(board: Board, name: str) -> int:
    address = board.symbol(name)
    assert address is not None, name
    return int(struct.unpack("<I", board.read_memory(address, 4))[0])


def make(elf: Path) -> Board:
    board = Board(PARTS["stm32g474"], elf)
    board.analog = lambda adc, channel, now: 3.3 if channel < 0 else {1: 1.0, 2: 2.0}.get(channel, 0.0)
    board.encoder = lambda timer, now: -(now // 100_000)  # turning backwards
    board.run_until(HCLK // 200)  # 5 ms
    return board


@pytest.fixture(scope="module")
def board(build_fw: Callable[..., Path], tim_adc_models: bool) -> Board:
    del tim_adc_models  # made with the models it names
    return make(build_fw("pwm_adc"))


def tim1(board: Board) -> Tim1:
    timer = board.peripherals["TIM1"]
    assert isinstance(timer, Tim1)
    return timer


def test_the_carrier_is_centre_aligned_20_khz(board: Board) -> None:
    assert tim1(board).carrier_cycles() == 2 * ARR
    assert tim1(board).update_period_cycles() == 2 * ARR  # RCR 1: one update per carrier period, at the valley


def test_injected_conversions_read_the_front_end_each_period(board: Board) -> None:
    assert u32(board, "jdr1") == round(1.0 / 3.3 * 4095)
    assert u32(board, "jdr2") == round(2.0 / 3.3 * 4095)
    # one JEOS interrupt per carrier period since TIM1 started
    assert abs(u32(board, "isr_count") - tim1(board).updates) <= 1


def test_adc_samples_just_after_the_trigger_near_the_peak(board: Board) -> None:
    adc = board.peripherals["ADC1"]
    sample_at, channel, _ = adc.sample_log[-2]  # type: ignore[attr-defined]
    assert channel == 1
    valley = tim1(board).last_update
    if sample_at < valley:
        valley -= 2 * ARR
    # OC4REF rises at CCR4 = ARR - 10 counting up; IN1 is sampled 12.5 ADC clocks (HCLK/4) later
    assert sample_at - valley == ARR - 10 + 50


def test_trigger_to_isr_latency_is_the_conversion_plus_entry(board: Board) -> None:
    latencies = board.isr[ADC_IRQ].latency
    assert latencies and set(latencies) == {12}  # JEOS (asserted at the conversion's end) to the first instruction


def test_preloaded_compare_applies_from_the_next_update(board: Board) -> None:
    timer = tim1(board)
    written = u32(board, "isr_count")  # the ISR writes CCR1 = its count
    assert timer.ccr[0] == written - 1  # still the previous period's value ...
    board.run_until(timer.last_update + 2 * ARR + 100)  # ... until the next update at the valley
    assert timer.ccr[0] == u32(board, "isr_count")
    assert timer.late_writes == 0


def test_an_isr_too_long_for_its_period_lands_its_compares_late(build_fw: Callable[..., Path]) -> None:
    late = make(build_fw("pwm_adc", "LATE"))
    timer = tim1(late)
    assert timer.late_writes >= timer.updates - 3
    assert timer.first_late_update is not None and timer.first_late_update <= 2


def test_encoder_mode_counts_the_board_encoder_modulo_arr(board: Board) -> None:
    count = u32(board, "enc_count")
    assert 0 <= count < 4096
    edges = board.encoder("TIM3", board.now)
    assert (count - edges) % 4096 < 3  # the ISR read it within the last microseconds
    assert u32(board, "enc_dir") == 1  # counting down
