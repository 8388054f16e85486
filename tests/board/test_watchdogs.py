"""WWDG and IWDG of the virtual STM32G474 against RM0440: counting at their clocks, the early wakeup interrupt, the
window, write protection and update flags, and a reset that ends the run naming the watchdog, driven as
HAL_WWDG_Init/HAL_IWDG_Init and their refresh calls drive them."""

from __future__ import annotations

import pytest

from pmsm_hil.errors import HilError
from pmsm_hil.sim_target.stm32g4.peripherals.base import REGISTRY, BoardError, Peripheral
from pmsm_hil.sim_target.stm32g4.peripherals.iwdg import LSI_HZ, Iwdg
from pmsm_hil.sim_target.stm32g4.peripherals.watchdog import WatchdogResetError
from pmsm_hil.sim_target.stm32g4.peripherals.wwdg import Wwdg
from tests.board.fake_bus import FakeBus

CR, CFR, SR = 0x0, 0x4, 0x8
WDGA, EWI = 1 << 7, 1 << 9
KR, PR, RLR, IWDG_SR, WINR = 0x0, 0x4, 0x8, 0xC, 0x10


class FakeRcc(Peripheral):
    """An RCC that reports an APB1 prescaler of 2."""

    def reset(self) -> None:
        pass

    def read(self, offset: int, size: int, now: int) -> int:
        raise AssertionError

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        raise AssertionError

    def apb_divider(self, bus: int) -> int:
        return 2 if bus == 1 else 1


@pytest.fixture()
def wwdg(bus: FakeBus) -> Wwdg:
    return bus.add_model("WWDG", Wwdg)


@pytest.fixture()
def iwdg(bus: FakeBus) -> Iwdg:
    return bus.add_model("IWDG", Iwdg)


def test_registered_with_rm0440_reset_values(wwdg: Wwdg, iwdg: Iwdg) -> None:
    assert {"WWDG", "IWDG"} <= set(REGISTRY)
    assert (wwdg.base, iwdg.base) == (0x4000_2C00, 0x4000_3000)
    assert [wwdg.read(o, 4, 0) for o in (CR, CFR, SR)] == [0x7F, 0x7F, 0]
    assert [iwdg.read(o, 4, 0) for o in (PR, RLR, IWDG_SR, WINR)] == [0, 0xFFF, 0, 0xFFF]
    assert wwdg.next_event(0) is None and iwdg.next_event(0) is None
    assert issubclass(WatchdogResetError, BoardError) and issubclass(WatchdogResetError, HilError)


def test_wwdg_early_wakeup_then_reset_when_not_refreshed(bus: FakeBus, wwdg: Wwdg) -> None:
    wwdg.write(CFR, 4, EWI | (3 << 11) | 0x50, 0)  # WDGTB 3: PCLK1 / 4096 / 8, window 0x50
    wwdg.write(CR, 4, WDGA | 0x7F, 0)
    tick = 4096 * 8
    assert wwdg.next_event(0) == (0x7F - 0x40) * tick
    assert wwdg.read(CR, 4, 5 * tick) == WDGA | 0x7A
    wwdg.advance((0x7F - 0x40) * tick)
    assert wwdg.read(SR, 4, (0x7F - 0x40) * tick) == 1 and bus.pended == [0]
    wwdg.write(SR, 4, 0, (0x7F - 0x40) * tick)  # the ISR clears EWIF by writing 0
    assert wwdg.read(SR, 4, 0) == 0 and bus.cleared == [0]
    assert wwdg.next_event((0x7F - 0x40) * tick) == (0x7F - 0x3F) * tick
    with pytest.raises(WatchdogResetError, match="watchdog reset by WWDG at cycle 2097152: counter fell to 0x3f"):
        wwdg.advance((0x7F - 0x3F) * tick)


def test_wwdg_refresh_inside_and_outside_the_window(bus: FakeBus, wwdg: Wwdg) -> None:
    bus.models["RCC"] = FakeRcc(bus)  # PCLK1 = HCLK / 2: a tick every 2 * 4096 cycles
    tick = 2 * 4096
    wwdg.write(CFR, 4, 0x50, 0)
    wwdg.write(CR, 4, WDGA | 0x7F, 0)
    wwdg.write(CR, 4, WDGA | 0x7F, (0x7F - 0x50) * tick)  # counter 0x50: inside the window
    assert wwdg.refreshes == 1 and wwdg.next_event(0x2F * tick) == (0x2F + 0x3F) * tick  # EWIF at 0x40
    with pytest.raises(WatchdogResetError, match="refreshed with the counter at 0x7e, above the window W = 0x50"):
        wwdg.write(CR, 4, WDGA | 0x7F, (0x2F + 1) * tick)
    wwdg.reset()
    with pytest.raises(WatchdogResetError, match="T6 clear"):
        wwdg.write(CR, 4, WDGA | 0x3F, 0)


def hal_iwdg_init(iwdg: Iwdg, prescaler: int, reload: int, window: int, now: int) -> int:
    """HAL_IWDG_Init: start, unlock, PR, RLR, wait for SR == 0, then WINR (reloads) or a refresh; returns the cycle
    it ends."""
    iwdg.write(KR, 4, 0xCCCC, now)
    iwdg.write(KR, 4, 0x5555, now)
    iwdg.write(PR, 4, prescaler, now)
    iwdg.write(RLR, 4, reload, now)
    polls = 0
    while iwdg.read(IWDG_SR, 4, now):
        now += 1000
        polls += 1
    assert polls > 0
    if window != 0xFFF:
        iwdg.write(WINR, 4, window, now)
    else:
        iwdg.write(KR, 4, 0xAAAA, now)
    return now


def test_iwdg_counts_at_lsi_and_resets_at_zero(bus: FakeBus, iwdg: Iwdg) -> None:
    now = hal_iwdg_init(iwdg, 4, 999, 0xFFF, 0)  # LSI / 64, 999 ticks: about 2 s
    tick = bus.sysclk_hz * 64 // LSI_HZ
    assert (now, iwdg.read(PR, 4, now), iwdg.read(RLR, 4, now)) == (now, 4, 999)
    assert now >= 6 * bus.sysclk_hz // LSI_HZ  # the update flags held for 6 LSI periods
    assert iwdg.next_event(now) == now + 999 * tick
    assert iwdg.counter(now + 10 * tick) == 989
    iwdg.write(KR, 4, 0xAAAA, now + 500 * tick)  # HAL_IWDG_Refresh
    assert iwdg.next_event(now) == now + 1499 * tick
    iwdg.write(PR, 4, 0, now + 600 * tick)  # locked again after the refresh key: ignored
    assert iwdg.read(PR, 4, 0) == 4 and iwdg.ignored_writes == 1
    iwdg.advance(now + 1499 * tick - 1)
    with pytest.raises(WatchdogResetError, match=r"watchdog reset by IWDG .*counter reached 0"):
        iwdg.advance(now + 1499 * tick)


def test_iwdg_window_reloads_on_write_and_resets_an_early_refresh(bus: FakeBus, iwdg: Iwdg) -> None:
    now = hal_iwdg_init(iwdg, 0, 0xFFF, 0x800, 0)  # LSI / 4, window: refresh only below 0x800
    tick = bus.sysclk_hz * 4 // LSI_HZ
    assert iwdg.counter(now) == 0xFFF  # reloaded by the WINR write
    with pytest.raises(WatchdogResetError, match="refreshed with the counter at 0xf9b, above the window"):
        iwdg.write(KR, 4, 0xAAAA, now + 100 * tick)
    iwdg.write(KR, 4, 0xAAAA, now + 0x800 * tick)  # counter 0x7ff: inside
    assert iwdg.counter(now + 0x800 * tick) == 0xFFF


def test_unmodelled_registers_are_named(wwdg: Wwdg, iwdg: Iwdg) -> None:
    with pytest.raises(BoardError, match=r"WWDG at offset 0x00c"):
        wwdg.read(0xC, 4, 0)
    with pytest.raises(BoardError, match=r"IWDG at offset 0x014"):
        iwdg.write(0x14, 4, 0, 0)
