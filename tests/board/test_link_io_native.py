"""The C functions the board's C link calls each period (c/tim1.c hil_tim1_compare_duties / hil_tim1_outputs,
c/adc.c hil_adc_front_take) against their Python references, bit for bit, on states the example firmware does not
reach: TIM1's compare duties with the dead-time correction over random PWM modes, polarities, enables, dead times,
clock divisions, counting modes and currents (zero, negative zero, NaN, infinities), and the ADC pair's table filled
from a front end equal to the table `Adc12Pair.set_inputs` fills from the pin voltages computed in Python; and the
encoder timer's CNT read (c/tim_gp.c) against GeneralTimer.counter, and never reaching Python in the example's run."""

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


class _EncoderBus(AnalogBus):
    """The fake board with the board link's encoder (BoardLink._encoder's formula) on TIM3."""

    def __init__(self) -> None:
        super().__init__({})
        self.theta_m, self.omega_m, self.period_start, self.hclk_hz, self.lines = 0.0, 0.0, 0, HCLK_HZ, 2048

    def encoder_position(self, timer: str, now: int) -> int:
        dt = (now - self.period_start) / self.hclk_hz
        theta = self.theta_m + self.omega_m * dt
        return math.floor(theta / (2 * math.pi) * 4 * self.lines)


ANGLES = (0.0, -0.0, 1e-9, -1e-9, 3.0, -3.0, 1234.5, -98765.4, 1e12, -1e12, math.nan, math.inf, -math.inf)


@pytest.mark.parametrize("seed", range(4))
def test_the_encoders_cnt_read_in_c_equals_the_model(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """c/tim_gp.c's CNT read against GeneralTimer.counter on random encoder modes (x2 on either input, x4), counting
    or stopped, ARR, CNT writes and angles both ways (negative counts: floor division and modulo as Python's),
    not finite or beyond 2^61 edges (handed to Python, which raises or takes the big integers)."""
    from unicorn.unicorn_py3.unicorn import MMIO_READ_CFUNC

    from pmsm_hil.sim_target.stm32g4.peripherals import tim_gp

    rng = random.Random(seed)
    ref_bus, nat_bus = _EncoderBus(), _EncoderBus()
    ref, nat = ref_bus.add("TIM3"), nat_bus.add("TIM3")
    assert isinstance(ref, tim_gp.Tim3) and isinstance(nat, tim_gp.Tim3)
    lib = tim_gp._typed(periph_native.library("tim_gp"))
    lib.hil_tim_gp_mmio_read.argtypes = [ctypes.c_void_p, ctypes.c_uint64, ctypes.c_uint, ctypes.c_void_p]
    lib.hil_tim_gp_mmio_read.restype = ctypes.c_uint64
    count = ctypes.c_uint64(0)
    state = tim_gp.TimGpState()
    state.count = ctypes.addressof(count)
    state.cnt_offset = nat.base + tim_gp.CNT - 0x4000_0000
    fallbacks: list[object] = []

    def fallback(_uc: int, offset: int, size: int, _user: int) -> int:
        try:  # as the board's decoder: Python's answer, or its error (the board raises it once the core stopped)
            value = nat.read(offset - (nat.base - 0x4000_0000), size, int(count.value))
        except (ValueError, OverflowError) as exc:
            fallbacks.append(type(exc))
            return 0
        fallbacks.append(value)
        return value

    keep = MMIO_READ_CFUNC(fallback)
    state.fallback_read = ctypes.cast(keep, ctypes.c_void_p).value
    nat._c = state
    nat._push()
    assert nat.arm_encoder(2048)
    for tim in (ref, nat):  # x4 encoder mode, counting
        tim.write(tim_gp.SMCR, 4, 3, 0)
        tim.write(tim_gp.CR1, 4, 1, 0)
    served = 0
    now = 1000
    for _ in range(800):
        now += rng.randrange(0, 20_000)
        count.value = now
        kind = rng.random()
        if kind < 0.08:
            word, value = rng.choice(((tim_gp.SMCR, rng.choice((0, 1, 2, 3, 3, 3))),
                                      (tim_gp.CR1, rng.choice((0, 1, 1))),
                                      (tim_gp.ARR, rng.choice((0xFFFF, 8191, 1000, 0))),
                                      (tim_gp.CNT, rng.randrange(1 << 16))))
            outcomes = []
            for tim in (ref, nat):
                try:
                    tim.write(word, 4, value, now)
                    outcomes.append(None)
                except (ValueError, OverflowError) as exc:  # the angle not finite: Python's error, in both
                    outcomes.append(type(exc))
            assert outcomes[0] == outcomes[1]
        elif kind < 0.4:
            theta = rng.choice(ANGLES) if rng.random() < 0.3 else rng.uniform(-1e4, 1e4)
            omega = math.nan if rng.random() < 0.05 else rng.choice((0.0, 157.0, -157.0, rng.uniform(-2e3, 2e3)))
            for bus in (ref_bus, nat_bus):
                bus.theta_m, bus.omega_m, bus.period_start = theta, omega, now - rng.randrange(0, 9000)
                bus.period_start = ref_bus.period_start
            nat.sync_encoder(theta, omega, ref_bus.period_start, HCLK_HZ)
        want: object
        got: object
        try:
            want = ref.read(tim_gp.CNT, 4, now)
        except (ValueError, OverflowError) as exc:
            want = type(exc)
        before = len(fallbacks)
        got = int(lib.hil_tim_gp_mmio_read(None, state.cnt_offset, 4, ctypes.addressof(state)))
        served += len(fallbacks) == before
        if len(fallbacks) > before:  # handed to Python: its answer or its error
            got = fallbacks[-1]
        assert got == want
        if want in (ValueError, OverflowError):
            continue
        assert (ref.read(tim_gp.CR1, 4, now), ref.last_edges) == (nat.read(tim_gp.CR1, 4, now), nat.last_edges)
    assert served > 200 and len(fallbacks) > 20
    # edges beyond 2^61 anchored by a CNT write: the C read hands the timer back to Python for good
    for bus in (ref_bus, nat_bus):
        bus.theta_m, bus.omega_m = 1e30, 0.0
    nat.sync_encoder(1e30, 0.0, ref_bus.period_start, HCLK_HZ)
    for tim in (ref, nat):
        tim.write(tim_gp.CNT, 4, 7, now)
    assert nat._c is None and state.armed == 0
    before = len(fallbacks)
    assert int(lib.hil_tim_gp_mmio_read(None, state.cnt_offset, 4, ctypes.addressof(state))) == \
        ref.read(tim_gp.CNT, 4, now) == 7 and len(fallbacks) == before + 1
    assert ref.read(tim_gp.CR1, 4, now) == nat.read(tim_gp.CR1, 4, now)
