"""TIM1 and ADC1/ADC2 in C against their Python reference on random register traffic (the fake board): the same
register values read back, the same next events, the same trigger edges, conversions and interrupt-line calls, op
for op — the modes and paths the example firmwares do not take (edge-aligned and down-counting, toggle and forced
modes, TRGO/TRGO2 selections, regular sequences, continuous mode, software starts, the break input)."""

from __future__ import annotations

import random
from typing import Any

import pytest

from pmsm_hil.sim_target.stm32g4 import periph_native
from pmsm_hil.sim_target.stm32g4.board import load_models
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import SIGNALS
from tests.board.test_adc_dma_opamp import AnalogBus

load_models()

TIM_WORDS = (0x00, 0x04, 0x0C, 0x10, 0x18, 0x1C, 0x20, 0x24, 0x28, 0x2C, 0x30, 0x34, 0x38, 0x3C, 0x40, 0x44, 0x48,
             0x4C, 0x50, 0x60)
ADC_WORDS = (0x00, 0x04, 0x08, 0x0C, 0x14, 0x18, 0x30, 0x34, 0x40, 0x4C, 0x80, 0x84, 0x88, 0x8C, 0xB4)


def _tim_value(rng: random.Random, word: int) -> int:
    if word == 0x00:  # CR1: CEN, UDIS, DIR, CMS, ARPE (never OPM)
        return rng.choice((0, 1, 1, 1)) | rng.choice((0, 0, 0, 2)) | rng.choice((0, 16)) | rng.randrange(4) << 5 | \
            rng.choice((0, 128))
    if word == 0x04:  # CR2: MMS, MMS2
        return rng.randrange(8) << 4 | rng.randrange(16) << 20
    if word in (0x18, 0x1C, 0x50):  # CCMRx: OCxM (with bit 16), OCxPE
        return sum((rng.randrange(8) << 4 | rng.choice((0, 8)) | rng.choice((0, 1 << 16))) << (8 * k)
                   for k in range(2)) & 0x0101_FFFF if word != 0x50 else \
            (rng.randrange(8) << 4 | rng.choice((0, 8)) | rng.randrange(8) << 12 | rng.choice((0, 1 << 11)))
    if word == 0x44:  # BDTR without BK2E
        return rng.randrange(1 << 16)
    if word == 0x60:  # AF1: BKINE, BKINP
        return rng.choice((0, 1)) | rng.choice((0, 1 << 9))
    if word in (0x28,):
        return rng.randrange(4)
    if word in (0x2C, 0x30):
        return rng.randrange(20, 120) if word == 0x2C else rng.randrange(3)
    if word == 0x10:
        return rng.randrange(1 << 8) | rng.choice((0, 0xFFFF_FFFF))
    return rng.randrange(130)


def _adc_value(rng: random.Random, word: int) -> int:
    if word == 0x08:  # CR: regulator, enable, starts and stops (never ADCAL while enabled)
        return 1 << 28 | rng.choice((0, 1, 1, 1)) | rng.choice((0, 4)) | rng.choice((0, 8)) | rng.choice((0, 0, 16)) | \
            rng.choice((0, 0, 32)) | rng.choice((0, 0, 0, 2))
    if word == 0x0C:  # CFGR: DMAEN off, RES, EXTSEL of TIM1's, EXTEN, OVRMOD, ALIGN; CONT with software starts only
        exten = rng.randrange(4)
        return 0x8000_0000 | rng.randrange(4) << 3 | rng.choice((0, 1, 2, 9, 10)) << 5 | exten << 10 | \
            rng.choice((0, 1 << 12)) | (rng.choice((0, 1 << 13)) if not exten else 0) | rng.choice((0, 1 << 15))
    if word == 0x4C:  # JSQR: JL, JEXTSEL of TIM1's, JEXTEN, channels
        return rng.randrange(4) | rng.choice((0, 1, 8)) << 2 | rng.randrange(4) << 7 | \
            sum(rng.randrange(19) << (9 + 6 * i) for i in range(4))
    if word in (0x14, 0x18):  # sampling times of 2.5 or 6.5 clocks (conversions faster than the triggers)
        return rng.randrange(1 << 30) & 0x0924_9249
    if word in (0x30, 0x34):
        return rng.randrange(1 << 30) & ~0xF | rng.randrange(3) if word == 0x30 else rng.randrange(1 << 30)
    if word == 0x04:
        return rng.randrange(1 << 11)
    return rng.randrange(1 << 11)


def trace(native: bool, seed: int, monkeypatch: pytest.MonkeyPatch, steps: int = 800) -> list[Any]:
    """What a random sequence of accesses and advances leaves, op by op."""
    monkeypatch.setattr(periph_native, "NATIVE", native)
    rng = random.Random(seed)
    bus = AnalogBus({("ADC1", ch): 0.1 * ch for ch in range(19)} | {("ADC2", ch): 0.15 * ch for ch in range(19)})
    models = {name: bus.add(name) for name in ("TIM1", "ADC12_COMMON", "ADC1", "ADC2")}
    assert (type(models["TIM1"]).__name__.startswith("Native")) == native
    out: list[Any] = []
    tim = models["TIM1"]
    for signal in SIGNALS:
        tim.subscribe(signal, lambda s, rising, at: out.append(("edge", s, rising, at)))  # type: ignore[attr-defined]
    models["ADC12_COMMON"].write(0x08, 4, rng.randrange(1, 3) << 16, 0)  # HCLK/1 or /2: faster than the triggers
    for name in ("ADC1", "ADC2"):
        models[name].write(0x08, 4, 1 << 28, 0)
        models[name].write(0x08, 4, 1 << 28 | 1, 1)
    now = 2
    for _ in range(steps):
        kind = rng.random()
        name = rng.choice(("TIM1", "TIM1", "ADC1", "ADC2"))
        model = models[name]
        try:
            if kind < 0.35:
                now += rng.randrange(1, 400)
                for m in (models["TIM1"], models["ADC1"], models["ADC2"]):
                    m.advance(now)
                out.append(("next", [m.next_event(now) for m in (models["TIM1"], models["ADC1"], models["ADC2"])]))
            elif kind < 0.75:
                word = rng.choice(TIM_WORDS if name == "TIM1" else ADC_WORDS)
                value = _tim_value(rng, word) if name == "TIM1" else _adc_value(rng, word)
                size = rng.choice((4, 4, 4, 2))
                model.write(word, size, value & ((1 << (8 * size)) - 1), now)
                out.append(("write", name, word, value))
            elif kind < 0.8 and name == "TIM1":
                tim.set_break_pin(rng.random() < 0.5, now)  # type: ignore[attr-defined]
            else:
                word = rng.choice(TIM_WORDS if name == "TIM1" else ADC_WORDS)
                out.append(("read", name, word, model.read(word, 4, now)))
        except BoardError as exc:
            out.append(("error", str(exc)))
        out.append(("lines", list(bus.pended), list(bus.cleared)))
        bus.pended.clear()
        bus.cleared.clear()
    out.append(("tim", tim.updates, tim.late_writes, tim.break_trips, tim.ccr))  # type: ignore[attr-defined]
    out.append(("adc", [(m.triggers, m.sample_log) for m in (models["ADC1"], models["ADC2"])]))  # type: ignore[attr-defined]
    return out


SEEDS = range(12)


@pytest.mark.parametrize("seed", SEEDS)
def test_random_traffic_gives_the_same_trace(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    reference = trace(False, seed, monkeypatch)
    native = trace(True, seed, monkeypatch)
    for i, (r, n) in enumerate(zip(reference, native, strict=True)):
        assert n == r, f"op {i} differs"


def test_the_random_traffic_reaches_the_triggers_and_conversions(monkeypatch: pytest.MonkeyPatch) -> None:
    traces = [trace(False, seed, monkeypatch) for seed in SEEDS]
    assert sum(1 for t in traces for entry in t if entry[0] == "edge") > 1000
    assert sum(t[-2][1] for t in traces) > 100  # update events
    assert sum(len(log) for t in traces for _, log in t[-1][1]) > 20  # injected samples
    assert sum(1 for t in traces for entry in t if entry[0] == "lines" and entry[1]) > 20  # lines asserted
