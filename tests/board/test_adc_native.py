"""The ADC pair in C (c/adc.c) beyond what the record comparisons cover (tests/board/test_native_exc.py): its
codes from the table of pin voltages a link fills once a period equal the Python reference's codes from the board's
analog front end, at every resolution and alignment, a conversion started from the table gives the same result
register as one that asks the front end, and the models' hil_periph_ops_t (for a scheduler in C) answer as they do."""

from __future__ import annotations

import ctypes
from typing import Any

import pytest

from pmsm_hil.sim_target.stm32g4 import periph_native
from pmsm_hil.sim_target.stm32g4.board import Board, load_models
from pmsm_hil.sim_target.stm32g4.part import PARTS
from pmsm_hil.sim_target.stm32g4.peripherals.adc_native import NativeAdc, pair_of
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from tests.board.test_adc_dma_opamp import ADEN, ADVREGEN, CFGR, CR, AnalogBus, enabled_adc1

load_models()

JSQR, JDR1, JADSTART = 0x4C, 0x80, 8
VOLTS = (-0.2, 0.0, 0.000402, 0.4, 1.0, 1.65, 1.6500001, 2.2, 3.2996, 3.3, 3.5)


@pytest.fixture(autouse=True)
def native(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(periph_native, "NATIVE", True)


@pytest.mark.parametrize("res", range(4))
@pytest.mark.parametrize("align", [0, 1])
def test_table_codes_equal_the_front_ends(res: int, align: int) -> None:
    bus = AnalogBus({})
    enabled_adc1(bus)
    adc = bus.models["ADC1"]
    assert isinstance(adc, NativeAdc)
    adc.regs[CFGR] = 0x8000_0000 | res << 3 | align << 15
    lib = pair_of(bus).lib
    for v in VOLTS:
        bus.volts[("ADC1", 3)] = v
        assert lib.hil_adc_code_of(ctypes.addressof(pair_of(bus).state.adc[0]), v, 3.3) == adc._code(3, 0), v


def test_a_conversion_from_the_table_gives_the_front_ends_code() -> None:
    results = []
    for table in (False, True):
        bus = AnalogBus({("ADC1", 3): 1.234, ("ADC1", 4): 2.5})
        now = enabled_adc1(bus)
        adc = bus.models["ADC1"]
        if table:
            pair_of(bus).set_inputs(3.3, dict(bus.volts))
            bus.volts.clear()  # the front end no longer asked: the codes come from the table
        adc.write(JSQR, 4, 1 | 3 << 9 | 4 << 15, now)  # JL = 1: IN3, IN4, software trigger
        adc.write(CR, 4, ADVREGEN | ADEN | JADSTART, now)
        adc.advance(now + 1000)
        results.append((adc.read(JDR1, 4, now + 1000), adc.read(JDR1 + 4, 4, now + 1000)))
    assert results[0] == results[1] == (round(1.234 / 3.3 * 4095), round(2.5 / 3.3 * 4095))


def test_a_table_entry_outside_the_pair_is_named() -> None:
    bus = AnalogBus({})
    enabled_adc1(bus)
    with pytest.raises(BoardError, match="ADC3 channel 1"):
        pair_of(bus).set_inputs(3.3, {("ADC3", 1): 1.0})


def test_the_ops_for_a_scheduler_in_c_answer_as_the_models(build_fw: Any) -> None:
    board = Board(PARTS["stm32g474"], build_fw("pwm_adc"))
    board.analog = lambda adc, channel, now: 3.3 if channel < 0 else 1.0
    for end in range(200_000, 2_000_000, 137_000):
        board.run_until(end)
        for name in ("TIM1", "ADC1", "ADC2"):
            model = board.peripherals[name]
            ops = periph_native.PeriphOps.from_address(model.c_ops())  # type: ignore[attr-defined]
            at = periph_native.NEXT_EVENT_FN(ops.next_event)(ops.self, board.now)
            assert (None if at < 0 else at) == model.next_event(board.now), name
    assert board.peripherals["TIM1"].updates > 10  # type: ignore[attr-defined]


def test_the_c_core_calls_the_models_in_c_and_raises_what_they_held(build_fw: Any) -> None:
    """Under the board's C core TIM1 and the ADCs are called without Python (their `native_ops`); an error an ADC
    held meanwhile (here its full-queue flag, set by hand) is raised when the core's call returns."""
    board = Board(PARTS["stm32g474"], build_fw("pwm_adc"))
    board.analog = lambda adc, channel, now: 3.3 if channel < 0 else 1.0
    board.run_until(400_000)
    assert board._native_core
    for name in ("TIM1", "ADC1", "ADC2"):
        assert not board._core.models[board._slot[board.peripherals[name]]].python, name
    adc = board.peripherals["ADC1"]
    assert isinstance(adc, NativeAdc)
    adc._a.error = 1
    with pytest.raises(BoardError, match=r"ADC1: more than .* conversions queued"):
        board.run_until(800_000)
