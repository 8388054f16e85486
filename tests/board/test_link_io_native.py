"""The C functions the board's C link calls each period (c/tim1.c hil_tim1_compare_duties / hil_tim1_outputs,
c/adc.c hil_adc_front_take) against their Python references, bit for bit, on states the example firmware does not
reach: TIM1's compare duties with the dead-time correction over random PWM modes, polarities, enables, dead times,
clock divisions, counting modes and currents (zero, negative zero, NaN, infinities), and the ADC pair's table filled
from a front end equal to the table `Adc12Pair.set_inputs` fills from the pin voltages computed in Python."""

from __future__ import annotations

import ctypes
import math
import random
import struct

import pytest

from pmsm_hil.sim_target.stm32g4 import periph_native
from pmsm_hil.sim_target.stm32g4.board import load_models
from pmsm_hil.sim_target.stm32g4.peripherals.adc_native import pair_of
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import Tim1
from pmsm_hil.sim_target.stm32g4.peripherals.tim1_native import NativeTim1
from tests.board.test_adc_dma_opamp import AnalogBus

load_models()

HCLK_HZ = 170_000_000
CURRENTS = (0.0, -0.0, 1.5, -2.0, 1e-300, -1e-300, math.nan, -math.nan, math.inf, -math.inf)
CR1, CCMR1, CCMR2, CCMR3, CCER, ARR, BDTR = 0x00, 0x18, 0x1C, 0x50, 0x20, 0x2C, 0x44
CCR = (0x34, 0x38, 0x3C, 0x40, 0x48, 0x4C)


def _bits(values: tuple[float, ...] | None) -> bytes | None:
    return None if values is None else struct.pack(f"<{len(values)}d", *values)


def _timer(native: bool, monkeypatch: pytest.MonkeyPatch) -> Tim1:
    monkeypatch.setattr(periph_native, "NATIVE", native)
    tim = AnalogBus({}).add("TIM1")
    assert isinstance(tim, Tim1) and isinstance(tim, NativeTim1) == native
    return tim


def _configure(tim: Tim1, rng: random.Random) -> None:
    """Random output configuration written as the firmware writes it, then an update event loading it."""
    arr = rng.choice((0, 1, 99, 4250, 0xFFFF))
    tim.write(ARR, 4, arr, 0)
    tim.write(CR1, 4, rng.randrange(4) << 5 | rng.randrange(4) << 8, 0)  # CMS, CKD; stopped
    tim.write(CCMR1, 4, sum((rng.randrange(8) << 4 | rng.choice((0, 1 << 16))) << (8 * k) for k in range(2)), 0)
    tim.write(CCMR2, 4, sum((rng.randrange(8) << 4 | rng.choice((0, 1 << 16))) << (8 * k) for k in range(2)), 0)
    tim.write(CCMR3, 4, rng.randrange(8) << 4 | rng.randrange(8) << 12, 0)
    tim.write(CCER, 4, rng.randrange(1 << 24), 0)
    for offset in CCR:
        tim.write(offset, 4, rng.choice((0, 1, arr // 3, arr, arr + 1, 0xFFFF)), 0)
    tim.write(BDTR, 4, rng.randrange(1 << 8) | rng.choice((0, 1 << 15, 1 << 15)), 0)
    tim.write(0x14, 4, 1, 1)  # EGR.UG: the preloaded values in force


@pytest.mark.parametrize("seed", range(6))
def test_the_compare_duties_in_c_equal_the_reference(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = random.Random(seed)
    reference, native = _timer(False, monkeypatch), _timer(True, monkeypatch)
    assert isinstance(native, NativeTim1)
    outputs = (ctypes.c_double * 3)()
    seen_moe = seen_off = 0
    for _ in range(60):
        state = rng.getstate()
        _configure(reference, rng)
        rng.setstate(state)
        _configure(native, rng)
        channels = tuple(rng.sample(range(6), 3))
        carrier_s = rng.choice((50e-6, 1 / 3 * 1e-4, 1e-3))
        function, user = native.outputs_function(channels, HCLK_HZ, carrier_s)
        call = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p)(function)
        for _ in range(8):
            currents = tuple(rng.choice(CURRENTS) for _ in range(3))
            want = reference.compare_duties(channels, currents, HCLK_HZ, carrier_s)
            assert _bits(native.compare_duties(channels, currents, HCLK_HZ, carrier_s)) == _bits(want)
            moe = call(user, (ctypes.c_double * 3)(*currents), outputs)
            assert moe == (want is not None) == native.moe == reference.moe
            if want is not None:
                assert _bits(tuple(outputs)) == _bits(want)  # the C link's entry point
                seen_moe += 1
            else:
                seen_off += 1
    assert seen_moe > 100 and seen_off > 20


def test_the_front_end_in_c_fills_the_table_set_inputs_fills(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(periph_native, "NATIVE", True)
    rng = random.Random(7)
    bus = AnalogBus({})
    pair = pair_of(bus)
    inputs = [("ADC1", 1, 1.65, 0.05, 0), ("ADC2", 2, 1.65, 0.05, 1), ("ADC1", 12, 0.0, 0.008, 3),
              ("ADC2", 31, 0.3, -0.1, 2), ("ADC1", 1, 1.0, 0.01, 2), ("ADC1", 18, 1.0, 1.0, 0)]  # ADC1 IN1 twice
    pair.set_front_end(inputs, 4, 3.3, 1.212)
    function, user = pair.take_function()
    call = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)(function)
    state = pair.state
    for _ in range(50):
        values = tuple(rng.choice((0.0, -0.0, rng.uniform(-100, 100), math.inf, math.nan)) for _ in range(4))
        volts: dict[tuple[str, int], float] = {}
        for adc, channel, offset, gain, signal in inputs:
            volts[(adc, channel)] = offset + gain * values[signal]
        pair.set_inputs(3.3, {**volts, ("ADC1", 18): 1.212})
        want = bytes(state.volts), state.vref
        ctypes.memset(ctypes.addressof(state.volts), 0xAB, ctypes.sizeof(state.volts))
        pair.take(values)
        assert (bytes(state.volts), state.vref, state.table_on) == (*want, 1)
        ctypes.memset(ctypes.addressof(state.volts), 0xAB, ctypes.sizeof(state.volts))
        call(user, (ctypes.c_double * 4)(*values))  # the C link's entry point
        assert (bytes(state.volts), state.vref, state.table_on) == (*want, 1)


def test_a_front_end_outside_the_table_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(periph_native, "NATIVE", True)
    pair = pair_of(AnalogBus({}))
    with pytest.raises(BoardError, match="ADC3 channel 1"):
        pair.set_front_end([("ADC3", 1, 0.0, 1.0, 0)], 4, 3.3, 1.212)
    with pytest.raises(BoardError, match="signal index 4"):
        pair.set_front_end([("ADC1", 1, 0.0, 1.0, 4)], 4, 3.3, 1.212)
    with pytest.raises(BoardError, match="before set_front_end"):
        pair.take((0.0, 0.0, 0.0, 0.0))


@pytest.mark.parametrize("native", [True, False], ids=["c", "python"])
def test_the_encoder_timers_cnt_is_read_in_c(native: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """The example firmware reads TIM3's CNT (its encoder) every period: with the C read armed no such read reaches
    the Python model (tests/board/test_native_exc.py's `native_encoder` path: the same records)."""
    from pmsm_hil.sim_target.stm32g4.peripherals import tim_gp
    from tests.board.test_native_exc import EXAMPLE_BOARD, example, records

    monkeypatch.setattr(tim_gp, "NATIVE_ENCODER", native)
    reads: list[int] = []
    read = tim_gp.GeneralTimer.read

    def counted(self: tim_gp.GeneralTimer, offset: int, size: int, now: int) -> int:
        if self.name == "TIM3" and offset == tim_gp.CNT and self.encoder_mode:  # the reads of the encoder
            reads.append(now)
        return read(self, offset, size, now)

    monkeypatch.setattr(tim_gp.GeneralTimer, "read", counted)
    out = records(example(), EXAMPLE_BOARD, True, monkeypatch, 200, native_encoder=native)  # asserts the arming
    assert sum(out["entries"]) >= 200 and out["encoder"][0][0] != 0  # the encoder turned
    assert reads == [] if native else len(reads) > 200
