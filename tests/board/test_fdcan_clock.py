"""FDCAN1's kernel clock from RCC CCIPR.FDCANSEL (HSE, PLL Q, PCLK1) and the firmware's bit timing checked against
the run's link when it leaves initialisation: a rate that differs, or a source that is not running, is one line
naming the register and the rates, not silent frames."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import can
import pytest

from pmsm_hil.sim_target.stm32g4.board import Board
from pmsm_hil.sim_target.stm32g4.board_file import load_board
from pmsm_hil.sim_target.stm32g4.frame_link import FrameBoardLink
from pmsm_hil.sim_target.stm32g4.part import PARTS
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.fdcan import Fdcan

RUN = 3_000_000  # cycles: the clock set-up and the FDCAN configuration


def board_with(elf: Path, bitrates: tuple[int | None, int | None]) -> tuple[Board, Fdcan]:
    board = Board(PARTS["stm32g474"], elf)
    fdcan = board.peripherals["FDCAN1"]
    assert isinstance(fdcan, Fdcan)
    fdcan.link_bitrates = bitrates
    return board, fdcan


def on_bus(board: Board) -> int:
    address = board.symbol("on_bus")
    assert address is not None
    return board.cpu.read_u32(address)


@pytest.mark.parametrize(("defines", "kernel_hz", "prescaler", "nominal"), [
    (("SEL=2",), 170_000_000, 5, 1_000_000),              # PCLK1: 170 MHz / (5 x 34)
    (("SEL=1", "QEN"), 170_000_000, 5, 1_000_000),        # PLL Q /2: 340 MHz VCO / 2
    (("SEL=0", "NBRP=0"), 24_000_000, 1, 705_882),        # HSE 24 MHz / 34
])
def test_the_kernel_clock_follows_fdcansel_and_a_matching_rate_joins_the_bus(
        build_fw: Callable[..., Path], defines: tuple[str, ...], kernel_hz: int, prescaler: int, nominal: int) -> None:
    board, fdcan = board_with(build_fw("fdcan_clock", *defines), (nominal, None))
    board.run_until(RUN)
    assert on_bus(board) == 1
    assert fdcan.kernel_clock_hz == kernel_hz
    # a frame's bus time follows the kernel clock: 8 more classic bytes are 64 nominal bits of 34 quanta each
    classic = [can.Message(arbitration_id=1, data=bytes(n), is_extended_id=False) for n in (8, 0)]
    extra = fdcan.frame_cycles(classic[0]) - fdcan.frame_cycles(classic[1])
    assert extra == pytest.approx(64 * 34 * prescaler * 170e6 / kernel_hz, abs=1)


def test_a_nominal_rate_other_than_the_links_is_one_line_naming_nbtp_and_both_rates(
        build_fw: Callable[..., Path]) -> None:
    board, _ = board_with(build_fw("fdcan_clock", "SEL=2"), (500_000, None))
    with pytest.raises(BoardError) as info:
        board.run_until(RUN)
    text = str(info.value)
    assert text.startswith("FDCAN1 NBTP 0x0a041a05: 1e+06 bit/s (170 kernel clock periods per bit at PCLK1 170 MHz), "
                           "the run's link is 500000 bit/s (link option bitrate)")
    assert "main" in text and "\n" not in text
    assert on_bus(board) == 0


def test_a_data_rate_other_than_the_links_is_named_with_dbtp_when_bit_rate_switching(
        build_fw: Callable[..., Path]) -> None:
    elf = build_fw("fdcan_clock", "SEL=2", "FD", "DBRP=1")  # 170 MHz / (2 x 34) = 2.5 Mbit/s
    board, _ = board_with(elf, (1_000_000, 5_000_000))
    with pytest.raises(BoardError, match=r"FDCAN1 DBTP 0x00011966: 2\.5e\+06 bit/s .*the run's link is 5000000 "
                                         r"bit/s \(link option data_bitrate\)"):
        board.run_until(RUN)
    board, _ = board_with(build_fw("fdcan_clock", "SEL=2", "FD"), (1_000_000, 5_000_000))
    board.run_until(RUN)
    assert on_bus(board) == 1
    board, _ = board_with(elf, (1_000_000, None))  # no data rate stated: not checked
    board.run_until(RUN)
    assert on_bus(board) == 1


def test_an_unclocked_source_is_named(build_fw: Callable[..., Path]) -> None:
    board, _ = board_with(build_fw("fdcan_clock", "SEL=1"), (None, None))  # PLL Q output not enabled
    with pytest.raises(BoardError, match=r"RCC CCIPR\.FDCANSEL = 01 \(PLL Q\) clocks FDCAN1, but the PLL's Q output "
                                         r"is not running \(RCC PLLCFGR\.PLLQEN 0, PLLRDY 1\)"):
        board.run_until(RUN)
    board, _ = board_with(build_fw("fdcan_clock", "SEL=0", "NO_HSE"), (None, None))  # the reset value, HSE off
    with pytest.raises(BoardError, match=r"RCC CCIPR\.FDCANSEL = 00 \(HSE\) clocks FDCAN1, but the HSE is not ready"):
        board.run_until(RUN)
    board, _ = board_with(build_fw("fdcan_clock", "SEL=3"), (None, None))
    with pytest.raises(BoardError, match=r"RCC CCIPR\.FDCANSEL = 11 is reserved"):
        board.run_until(RUN)


def test_the_run_link_checks_the_firmware_api_image_too(build_fw: Callable[..., Path]) -> None:
    """FrameBoardLink (a firmware on FDCAN1) refuses at start-up with the same line."""
    with pytest.raises(BoardError, match=r"FDCAN1 NBTP .*the run's link is 500000 bit/s"):
        FrameBoardLink(build_fw("fdcan_clock", "SEL=2"), load_board(), ts_s=50e-6, can_bitrates=(500_000, None))


def test_hil_run_names_the_bit_rate_the_link_states(build_fw: Callable[..., Path], tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """`hil run --link virtual,bitrate=500000`: the firmware's 1 Mbit/s ends the run in its start-up (exit 3, the
    one line in metrics.json)."""
    from tests.board.test_run_endings import ending, hil_run

    out = tmp_path / "run"
    reason = ending(hil_run(capsys, build_fw("fdcan_clock", "SEL=2"), out, "--link", "virtual,bitrate=500000"), out)
    assert reason.startswith("target stopped in its start-up, before the first period: FDCAN1 NBTP 0x0a041a05: "
                             "1e+06 bit/s (170 kernel clock periods per bit at PCLK1 170 MHz), the run's link is "
                             "500000 bit/s (link option bitrate)")


@pytest.mark.parametrize("link", ["vcan0", "virtual,bitrate=500000,key=00", "virtual,bitrate=fast"])
def test_a_link_other_than_the_boards_rates_is_a_usage_error(build_fw: Callable[..., Path], tmp_path: Path,
                                                             link: str, capsys: pytest.CaptureFixture[str]) -> None:
    from tests.board.test_run_endings import hil_run

    proc = hil_run(capsys, build_fw("fdcan_clock", "SEL=2"), tmp_path / "run", "--link", link)
    assert proc.returncode == 2, proc.stderr[-2000:]
    last = proc.stderr.strip().splitlines()[-1]
    assert "--link" in last and "Traceback" not in proc.stderr


def test_a_clock_change_after_the_controller_joined_the_bus_is_followed(build_fw: Callable[..., Path]) -> None:
    """PCLK1 halved (APB1 /2) once FDCAN1 is on the bus at PCLK1: its bit times double from then on, as on the chip;
    with the run's link stating 1 Mbit/s the firmware no longer hears the bus: one line naming NBTP, both rates."""
    elf = build_fw("fdcan_clock", "SEL=2", "PPRE1_AFTER")
    board, fdcan = board_with(elf, (None, None))
    board.run_until(RUN)
    assert on_bus(board) == 2
    assert fdcan.kernel_clock_hz == 85_000_000
    classic = [can.Message(arbitration_id=1, data=bytes(n), is_extended_id=False) for n in (8, 0)]
    assert fdcan.frame_cycles(classic[0]) - fdcan.frame_cycles(classic[1]) == pytest.approx(64 * 34 * 5 * 2, abs=1)
    board, _ = board_with(elf, (1_000_000, None))
    with pytest.raises(BoardError) as info:
        board.run_until(RUN)
    assert str(info.value).startswith("FDCAN1 NBTP 0x0a041a05: 500000 bit/s (170 kernel clock periods per bit at "
                                      "PCLK1 85 MHz), the run's link is 1000000 bit/s (link option bitrate)")
    assert on_bus(board) == 1  # joined at 1 Mbit/s; the prescaler's write is where it stops
