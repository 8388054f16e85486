"""Link budget: the hand calculation of docs/protocol.md, FD and serial formulas, CLI output."""

from __future__ import annotations

import argparse
import json

import pytest

from pmsm_hil.app.cli import link_budget as cli
from pmsm_hil.app.cli.main import main
from pmsm_hil.protocol.errors import BudgetError
from pmsm_hil.protocol.links.budget import can_frame_bits, canfd_frame_bits, link_budget, serial_frame_bytes


def test_classic_can_hand_calculation() -> None:
    """docs/protocol.md: 1 Mbit/s, 3 phases, MeasA/MeasB 8 B, CmdA/CmdB/CmdC 8 B (CmdC byte 7: mirror)."""
    assert can_frame_bits(8) == 47 + 64 + 24 == 135
    assert can_frame_bits(7) == 47 + 56 + 22 == 125
    b = link_budget("can", 3, bitrate=1_000_000, rate_hz=1000)
    assert (b.frames_per_period_up, b.frames_per_period_down) == (2, 3)
    assert (b.bits_up_worst, b.bits_down_worst, b.bits_per_period_worst) == (270, 405, 675)
    assert b.wire_time_per_period_us == pytest.approx(675.0)
    assert b.bus_load_pct == pytest.approx(67.5)
    assert b.max_rate_hz == pytest.approx(1e6 / 675)
    assert b.feasible is True
    assert link_budget("can", 3, rate_hz=2000).feasible is False


def test_canfd_and_serial_formulas() -> None:
    assert canfd_frame_bits(16) == (34, 5 + 128 + (37 - 4) + 4 + 17 + 6)
    assert canfd_frame_bits(20) == (34, 5 + 160 + (45 - 4) + 4 + 21 + 7)
    b = link_budget("canfd", 3, bitrate=1_000_000, data_bitrate=5_000_000)
    assert b.wire_time_up_us == pytest.approx(34 + 193 / 5)
    assert b.bus_load_pct is None and b.feasible is None
    assert serial_frame_bytes(16) == 7 + 16 + 2 + 1 + 1
    s = link_budget("serial", 3, baud=1_000_000, rate_hz=1000)
    assert s.bits_up_worst == 270 and s.wire_time_up_us == pytest.approx(270.0)
    assert s.bus_load_pct == pytest.approx(max(s.wire_time_up_us, s.wire_time_down_us) / 10)


def test_six_phase_adds_reserved_frames() -> None:
    assert link_budget("can", 6).frames_per_period_up == 3
    assert link_budget("canfd", 6).payloads_up == (24,)
    assert link_budget("can", 6).max_rate_hz < link_budget("can", 3).max_rate_hz


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"link": "lin"}, "link"),
        ({"link": "can", "phases": 5}, "phases"),
        ({"link": "can", "bitrate": 0}, "bitrate"),
        ({"link": "serial", "baud": -1}, "baud"),
        ({"link": "can", "rate_hz": float("nan")}, "rate_hz"),
    ],
)
def test_budget_errors(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(BudgetError, match=match):
        link_budget(**kwargs)  # type: ignore[arg-type]


def parse(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    cli.add_parser(p.add_subparsers())
    return p.parse_args(["link-budget", *argv])


def test_cli_json(capsys: pytest.CaptureFixture[str]) -> None:
    args = parse(["--link", "can", "--bitrate", "1000000", "--phases", "3", "--rate", "1000", "--json"])
    assert args.func(args) == 0
    d = json.loads(capsys.readouterr().out)
    for key in (
        "frames_per_period_up",
        "frames_per_period_down",
        "bits_per_period_worst",
        "wire_time_per_period_us",
        "bus_load_pct",
        "max_rate_hz",
    ):
        assert key in d
    assert d["bits_per_period_worst"] == 675 and d["bus_load_pct"] == pytest.approx(67.5)


def test_cli_text_and_error(capsys: pytest.CaptureFixture[str]) -> None:
    args = parse(["--link", "serial", "--baud", "3000000", "--phases", "6", "--rate", "4000"])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "serial" in out and "max closed-loop rate" in out
    assert main(["link-budget", "--link", "can", "--bitrate", "-5"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith("hil: error: ") and "bitrate" in err and len(err.splitlines()) == 1


def test_cli_too_slow_exits_1(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["link-budget", "--link", "can", "--bitrate", "1000000", "--rate", "10000"]) == 1
    out, err = capsys.readouterr()
    assert "TOO SLOW" in out and err.startswith("hil: link-budget: too slow: can carries at most 1481 Hz")
    assert main(["link-budget", "--link", "canfd", "--rate", "5000"]) == 0
    assert "(fits)" in capsys.readouterr().out


def test_duty_cycle_commands_are_budgeted() -> None:
    """--command duties: classic CmdDutyA/B/C (3 × 8 bytes, as CmdA/B/C), CAN FD one 24-byte CmdDutyFd."""
    can = link_budget("can", command="duties")
    assert can.payloads_down == (8, 8, 8) and can.bits_down_worst == 3 * can_frame_bits(8)
    fd, fd_states = link_budget("canfd", command="duties"), link_budget("canfd")
    assert fd.payloads_down == (24,) and fd_states.payloads_down == (20,)
    assert fd.bits_down_worst == sum(canfd_frame_bits(24)) > fd_states.bits_down_worst
    with pytest.raises(BudgetError, match="command='pwm'"):
        link_budget("can", command="pwm")
    assert main(["link-budget", "--link", "canfd", "--command", "duties", "--rate", "5000"]) == 0
