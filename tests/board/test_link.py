"""The virtual board as the run's target: one firmware period per Measurement, duty-cycle Commands from TIM1's
compare values in force with the dead time by current sign, the carrier period checked against the run's, the
board's answers without a bus, and a fault inside a run ending it as a safety stop naming the function."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from pmsm_hil.protocol.codec import FrameCodec, FrameDecoder
from pmsm_hil.protocol.messages import Command, ConfigAck, ConfigParam, Heartbeat, Measurement, Setpoint
from pmsm_hil.sim_target.stm32g4.board_file import load_board
from pmsm_hil.sim_target.stm32g4.link import BoardLink
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError

TS = 50e-6
ARR = 4250
CODEC = FrameCodec("canfd")


def exchange(link: BoardLink, msg: object) -> list[object]:
    link.send(CODEC.encode(msg))  # type: ignore[arg-type]
    decoder, out = FrameDecoder(ordered=False), []
    while (frame := link.poll()) is not None:
        got = decoder.feed(frame)
        if got is not None:
            out.append(got)
    return out


def measurement(seq: int, i_a: float = 2.0) -> Measurement:
    return Measurement(seq=seq, i_a=i_a, i_b=-1.0, i_c=-1.0, theta_e=0.1 * seq, omega_m=10.0, vdc=48.0)


@pytest.fixture
def link(build_fw: Callable[..., Path]) -> BoardLink:
    return BoardLink(build_fw("pwm_adc"), load_board(), ts_s=TS, pole_pairs=4)


def test_each_measurement_runs_one_period_and_answers_with_the_compares_in_force(link: BoardLink) -> None:
    replies = [exchange(link, measurement(seq)) for seq in range(5)]
    assert all(len(r) == 1 and isinstance(r[0], Command) for r in replies)
    last = replies[-1][0]
    assert isinstance(last, Command) and last.seq == 4
    tim = link.tim1
    dead = tim.dead_time_s(link.hclk_hz) / TS
    # the firmware writes CCR1 = its ISR count (preloaded), CCR2 = 1000, CCR3 = 3000, PWM mode 1, active high
    wire = 1 / 65520  # the duty wire code's step
    assert last.duties[0] == pytest.approx(max(tim.ccr[0] / ARR - dead, 0.0), abs=wire)  # i_a > 0: shortened
    assert last.duties[1] == pytest.approx(1000 / ARR + dead, abs=wire)  # i_b < 0: lengthened
    assert last.duties[2] == pytest.approx(3000 / ARR + dead, abs=wire)
    assert last.exec_time_ns > 0  # the ADC handler's cycles in the period
    # ADC1 saw the front end's voltages: IN1 = i_a = 2 A, IN2 = i_c = -1 A at 1.65 V + 0.01 V/A
    log = link.board.peripherals["ADC1"].sample_log  # type: ignore[attr-defined]
    assert log[-2][1:] == (1, round((1.65 + 0.01 * 2.0) / 3.3 * 4095))
    assert log[-1][1:] == (2, round((1.65 - 0.01) / 3.3 * 4095))


def test_a_period_other_than_the_firmware_carrier_is_refused_naming_both(build_fw: Callable[..., Path]) -> None:
    refusal = r"carrier period is 50 µs .*TIM1 ARR 4250.*--ts is 100 µs: run with --ts 5e-05"
    with pytest.raises(BoardError, match=refusal):
        BoardLink(build_fw("pwm_adc"), load_board(), ts_s=100e-6, pole_pairs=4)


def test_without_a_bus_the_board_acks_configs_and_cuts_the_outputs_on_disable(link: BoardLink) -> None:
    acks = exchange(link, ConfigParam(param_id=3, value=1.5))
    assert acks == [ConfigAck(param_id=3, value=1.5, status=0)]
    assert exchange(link, Setpoint(enable=True, mode=0, reference=100.0, controller_id=1)) == []
    beat = exchange(link, Setpoint(enable=False, mode=0, reference=0.0, controller_id=1))
    assert len(beat) == 1 and isinstance(beat[0], Heartbeat) and beat[0].state == 1
    assert not link.tim1.moe
    cmd = exchange(link, measurement(0))[0]
    assert isinstance(cmd, Command) and cmd.duties == (0.5, 0.5, 0.5)
    metrics = link.metrics()
    assert metrics["board_configs_acked"] == 1 and metrics["board_setpoints_dropped"] == 1


@pytest.mark.slow
def test_a_fault_in_a_run_is_a_safety_stop_naming_the_handler(build_fw: Callable[..., Path], tmp_path: Path) -> None:
    elf = build_fw("pwm_adc", "FAULT_AT=300")
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "pmsm_hil.app.cli.main", "run", "--target", f"stm32g4:{elf}",
                           "--ts", str(TS), "--duration", "0.02", "--settle", "0.005", "--out", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 3, proc.stderr[-2000:]
    metrics = json.loads((out / "metrics.json").read_text())
    reason = metrics["end_reason"]
    assert "HardFault at pc 0x080" in reason and "(ADC1_2_IRQHandler+0x" in reason and "PRECISERR" in reason


def test_two_runs_give_identical_commands(build_fw: Callable[..., Path]) -> None:
    def commands() -> list[object]:
        link = BoardLink(build_fw("foc_bench"), load_board(), ts_s=TS, pole_pairs=4)
        return [exchange(link, measurement(seq, i_a=0.5 * (seq % 7) - 1.5)) for seq in range(60)]

    first = commands()
    assert first == commands()
    assert len({c[0].duties for c in first if isinstance(c[0], Command)}) > 10  # type: ignore[attr-defined]


def test_a_bad_board_file_names_the_field(tmp_path: Path) -> None:
    assert load_board().name == "nucleo_g474re_ihm"  # the default
    bad = tmp_path / "board.toml"
    source = (Path(__file__).parents[2] / "src/pmsm_hil/sim_target/stm32g4/boards/nucleo_g474re_ihm.toml").read_text()
    bad.write_text(source.replace('adc = "ADC2"', 'adc = "ADC3"', 1))
    with pytest.raises(BoardError, match=r"\[\[analog\]\] #2: 'adc' = 'ADC3' \(one of ADC1, ADC2\)"):
        load_board(bad)
    with pytest.raises(BoardError, match="no such board"):
        load_board("no_such_board")


def test_every_board_metric_is_registered(link: BoardLink) -> None:
    from pmsm_hil.hil.metrics.registry import METRICS

    for seq in range(3):
        exchange(link, measurement(seq))
    registered = {m.key for m in METRICS}
    produced = set(link.metrics())
    assert produced - registered == set()
    assert {"board_isr_time_us", "board_cpu_load", "board_handlers", "board_adc_sample_us"} <= produced


def test_with_moe_off_the_bridge_is_open_and_the_pins_start_at_zero_signal(build_fw: Callable[..., Path]) -> None:
    desc = load_board()
    link = BoardLink(build_fw("pwm_adc"), desc, ts_s=TS, pole_pairs=4, psi_f_wb=0.1, vdc_v=48.0)
    # before any Measurement the pins read the front end's zero-signal voltages (the nominal DC link for vdc)
    for a in desc.analog:
        expected = a.offset_v + a.gain * (48.0 if a.signal == "vdc" else 0.0)
        assert link._analog(a.adc, a.channel, link.board.now) == pytest.approx(expected)
    link.tim1.trip_break()
    m = measurement(3)
    cmd = exchange(link, m)[0]
    assert isinstance(cmd, Command)
    we = 4 * m.omega_m
    theta = m.theta_e + 1.5 * we * TS  # the middle of the period the Command is applied over
    emf = [-we * 0.1 * math.sin(theta - k * 2 * math.pi / 3) for k in range(3)]
    mid = (max(emf) + min(emf)) / 2
    wire = 1 / 65520
    assert cmd.duties == pytest.approx([0.5 + (e - mid) / m.vdc for e in emf], abs=wire)
    # the line voltages the open bridge's Command applies are the back EMF's: no current is driven
    assert cmd.duties[0] - cmd.duties[1] == pytest.approx((emf[0] - emf[1]) / m.vdc, abs=2 * wire)
