"""examples/stm32g4_foc on the virtual STM32G474's models (its Cortex-M4F core, TIM1, ADC1/ADC2, TIM3, FDCAN1,
USART2), closed through an average-value niu2020 plant: TIM1's duty cycles drive the plant, the plant's phase
currents reach the ADC through the board's front end (include/board.h), its angle the encoder. The frames of the
project's DBC go in through the FDCAN1 model. Skipped without arm-none-eabi-gcc or the board package."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.sim_target.fw_build import build_firmware, missing_tools
from tests.firmware._niu2020_avg import VDC, AvgPlant, duties_to_alpha_beta

board_mod = pytest.importorskip("pmsm_hil.sim_target.stm32g4.board", reason="the virtual STM32G4 board is absent")
part_mod = pytest.importorskip("pmsm_hil.sim_target.stm32g4.part", reason="the virtual STM32G4 board is absent")

HCLK = 170_000_000
W_REF = 1500.0 * 2 * math.pi / 60
COUNTS = 4 * 2048  # include/board.h BOARD_ENCODER_LINES, x4


def _elf(*defines: str) -> Path:
    missing = missing_tools("stm32g474")
    if missing:
        pytest.skip(f"firmware board stm32g474: {', '.join(missing)} not installed")
    return build_firmware("stm32g474", defines=list(defines)).path


class ClosedLoop:
    """The board and the plant, advanced half a carrier period at a time (valley, peak)."""

    def __init__(self, elf: Path) -> None:
        import can
        import cantools

        self.can = can
        self.db = cantools.database.load_file(str(Path(__file__).resolve().parents[2] / "src" / "pmsm_hil" /
                                                  "protocol" / "hil.dbc"))
        self.plant = AvgPlant(omega_m=W_REF, load=7.0)
        self.board: Any = board_mod.Board(part_mod.PARTS["stm32g474"], elf)
        self.board.analog = self._analog
        self.board.encoder = lambda timer, now: math.floor(self.plant.theta_m / (2 * math.pi) * COUNTS)
        self.board.run_until(HCLK // 1000)  # boot: clocks, ADC calibration, timers started
        self.tim1 = self.board.peripherals["TIM1"]
        assert self.tim1.running, "TIM1 does not run after boot"
        self.valley = self.tim1.last_update
        self.carrier = self.tim1.carrier_cycles()

    def _analog(self, adc: str, channel: int, now: int) -> float:
        if channel < 0:
            return 3.3
        ia, ib = self.plant.phase_ab()
        return {1: 1.65 + 0.05 * ia, 2: 1.65 + 0.05 * ib, 12: VDC * 0.008}.get(channel, 0.0)

    def send(self, name: str, **signals: float) -> None:
        msg = self.db.get_message_by_name(name)
        frame = self.can.Message(arbitration_id=msg.frame_id, is_extended_id=False, data=msg.encode(signals))
        self.board.peripherals["FDCAN1"].deliver(frame, self.board.now)

    def sent(self) -> list[str]:
        return [self.db.get_message_by_frame_id(f.arbitration_id).name
                for f in self.board.peripherals["FDCAN1"].take_transmitted()]

    def period(self) -> tuple[float, float]:
        """One carrier period; (speed [rpm], torque [N·m]) at its end."""
        ts = self.carrier / HCLK
        self.board.run_until(self.valley + 1)
        volts = duties_to_alpha_beta([self.tim1.duty(ch) for ch in range(3)])
        on = bool(self.tim1.moe)
        self.plant.advance(*volts, ts / 2, conducting=on)
        self.board.run_until(self.valley + self.carrier // 2 + 3000)  # the peak's conversions and current loop
        self.plant.advance(*volts, ts / 2, conducting=on)
        self.valley += self.carrier
        return self.plant.omega_m * 60 / (2 * math.pi), self.plant.torque()


def _run(elf: Path, seconds: float) -> tuple[ClosedLoop, float, float]:
    loop = ClosedLoop(elf)
    n = int(seconds * 20000)
    tail: list[tuple[float, float]] = []
    for k in range(n):
        if k == 80:  # after the 64-period offset measurement: the host's set-up and enabling Setpoint
            loop.send("ConfigParam", param_id=11, value=7.0)
            loop.send("Setpoint", enable=1, mode=0, reference=W_REF, controller_id=255)
        out = loop.period()
        if k >= n // 2:
            tail.append(out)
    rpm = sum(s for s, _ in tail) / len(tail)
    torque = sum(t for _, t in tail) / len(tail)
    return loop, rpm, torque


def test_holds_1500_rpm_and_7_nm_on_the_board_models() -> None:
    loop, rpm, torque = _run(_elf(), 0.15)
    adc_isr = loop.board.isr.get(16 + 18)
    assert adc_isr is not None and adc_isr.entries > 2000, "the current loop (ADC1_2_IRQHandler) did not run"
    assert loop.sent() == ["ConfigAck"]
    assert rpm == pytest.approx(1500.0, rel=0.005)
    assert torque == pytest.approx(7.0, rel=0.01)
    assert loop.tim1.late_writes == 0


def test_late_isr_variant_lands_its_compare_values_a_period_late() -> None:
    loop, rpm, _ = _run(_elf("LATE_ISR"), 0.15)
    adc_isr = loop.board.isr.get(16 + 18)
    assert adc_isr is not None and adc_isr.entries > 2000, "the current loop (ADC1_2_IRQHandler) did not run"
    assert sorted(adc_isr.cycles)[len(adc_isr.cycles) // 2] > loop.carrier // 2  # longer than peak to valley
    assert loop.tim1.late_writes > 500
    assert rpm == pytest.approx(1500.0, rel=0.01)


def test_fault_variant_stops_with_pc_and_cfsr_of_the_bus_fault() -> None:
    board: Any = board_mod.Board(part_mod.PARTS["stm32g474"], _elf("FAULT"))
    board.analog = lambda adc, channel, now: 3.3 if channel < 0 else 1.65
    fault: Exception | None = None
    try:
        board.run_until(HCLK // 1000 * 130)  # FAULT_AT_ISR 2000 current-loop runs: 100 ms
    except Exception as exc:  # the board's fault report
        fault = exc
    assert fault is not None, "the FAULT variant ran 130 ms without a fault"
    text = str(fault)
    assert "ADC1_2_IRQHandler+" in text and "PRECISERR" in text and "BFARVALID" in text and "0x20020000" in text
