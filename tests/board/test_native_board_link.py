"""The native loop's C link to the virtual board (c/links/link_board.h, hil/runner/board_native_link.py): a run of
the example firmware through it — the Measurement decoded and the duty-cycle Command encoded in C, the board called
once a period with plain numbers, the ADC table filled and TIM1's duties read by the C link through the models' C
functions — logs the same periods and frames, bit for bit, and the same board metrics as the same run through the
callback link alone (every frame through Python's codec) and as the C link leaving the table and the duties to the
board's Python (NativeBoardLink.NATIVE_IO off)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.runlog.reader import read_frames, read_periods, read_topic_messages
from pmsm_hil.hil.runlog.topics import TOPIC_BOARD
from pmsm_hil.hil.runner import loop_run
from pmsm_hil.hil.runner.board_native_link import NativeBoardLink
from pmsm_hil.hil.runner.run import run_from_options
from pmsm_hil.sim_target.stm32g4.link import BoardLink
from tests.board.test_run_endings import TS, _example_firmware

#: the board's metrics that must not depend on the link (wall times left out)
BOARD_KEYS = ("board_isr_time_us", "board_cpu_load", "board_late_compares", "board_idle_periods",
              "board_handlers", "board_configs_acked", "board_setpoints_dropped", "board_first_late_period",
              "board_break_trips", "speed_mean_rpm", "end_code",
              "end_period")


def _run(out: Path, monkeypatch: pytest.MonkeyPatch, *, c_link: bool, native_io: bool = True,
         native_period: bool = True) -> tuple[dict[str, Any], int, int, int]:
    """The run's metrics, its calls of `measurement`, how many of them left the duties to the C link, and the
    periods the board's period in C ran without Python (c/board_period.c)."""
    elf, board = _example_firmware()
    calls = in_c = 0
    links: list[BoardLink] = []
    measurement = BoardLink.measurement

    def counted(self: BoardLink, *args: Any) -> Any:
        nonlocal calls, in_c
        calls += 1
        out = measurement(self, *args)
        in_c += out is not None and out[0] is None
        return out

    def setup(self: BoardLink) -> None:
        links.append(self)
        setup_period(self)

    setup_period = BoardLink._setup_period
    with monkeypatch.context() as m:
        m.setattr(BoardLink, "measurement", counted)
        m.setattr(BoardLink, "_setup_period", setup)
        m.setattr(BoardLink, "NATIVE_PERIOD", native_period)
        m.setattr(NativeBoardLink, "NATIVE_IO", native_io)
        if not c_link:
            m.setattr(loop_run, "_board_link", lambda *args: None)
        res = run_from_options({"target": f"stm32g4:{elf}", "board": str(board), "ts": TS, "link": "virtual",
                                "controller": "external", "motor": "niu2020-ipmsm", "speed": 1500, "load": 7,
                                "duration": 0.01, "settle": 0.002, "out": str(out)})
    return res.metrics, calls, in_c, sum(int(link._ps.in_c) for link in links)


def test_the_c_board_link_logs_what_the_callback_link_logs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    fast, fast_calls, _, fast_periods = _run(tmp_path / "c", monkeypatch, c_link=True)
    no_period, np_calls, np_in_c, np_periods = _run(tmp_path / "no_period", monkeypatch, c_link=True,
                                                    native_period=False)
    py_io, py_io_calls, py_io_in_c, py_io_periods = _run(tmp_path / "py_io", monkeypatch, c_link=True,
                                                         native_io=False)
    slow, slow_calls, _, _ = _run(tmp_path / "py", monkeypatch, c_link=False)
    assert fast["end_code"] == 0, fast["end_reason"]
    periods = round(0.012 / TS)
    # the C link took the Measurements (most of them without Python: the period in C), the other did not
    assert fast_calls + fast_periods >= periods - 1 and fast_periods >= periods // 2 and slow_calls == 0
    assert np_periods == py_io_periods == 0 and np_calls == py_io_calls == fast_calls + fast_periods
    assert np_in_c >= periods // 2 and py_io_in_c == 0  # the duties from C or not
    names = ("c", "no_period", "py_io")
    for name in (*names, "py"):
        assert len(read_periods(tmp_path / name / "run.mcap")) >= periods - 1
    reference = read_periods(tmp_path / "py" / "run.mcap").tobytes()
    board_reference = read_topic_messages(tmp_path / "py" / "run.mcap", TOPIC_BOARD)
    slow_frames = read_frames(tmp_path / "py" / "run.mcap")
    assert len(slow_frames) > 2 * periods and len(board_reference) >= periods - 1
    for name, metrics in zip(names, (fast, no_period, py_io), strict=True):
        assert read_periods(tmp_path / name / "run.mcap").tobytes() == reference, name
        assert np.array_equal(read_frames(tmp_path / name / "run.mcap"), slow_frames), name
        assert [m.data for m in read_topic_messages(tmp_path / name / "run.mcap", TOPIC_BOARD)] == \
            [m.data for m in board_reference], name
        for key in BOARD_KEYS:
            assert metrics.get(key) == slow.get(key), (name, key)


def test_the_period_in_c_logs_what_python_logs_over_a_longer_run(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """Over 2000 periods (the C core's ISR log fills: the period in C hands its run back to Python, which finishes it;
    the main thread reads the C period's ring while it runs), the logged run with the period in C and without it:
    the same `/periods`, `/board/periods`, `/frames` and board metrics."""
    elf, board = _example_firmware()
    metrics = []
    for name, native_period in (("c", True), ("py", False)):
        with monkeypatch.context() as m:
            m.setattr(BoardLink, "NATIVE_PERIOD", native_period)
            res = run_from_options({"target": f"stm32g4:{elf}", "board": str(board), "ts": TS, "link": "virtual",
                                    "controller": "external", "motor": "niu2020-ipmsm", "speed": 1500, "load": 7,
                                    "duration": 0.1, "settle": 0.002, "out": str(tmp_path / name)})
        assert res.metrics["end_code"] == 0, res.metrics["end_reason"]
        metrics.append({k: v for k, v in res.metrics.items() if k.startswith("board_") and "wall" not in k})
    c, py = tmp_path / "c" / "run.mcap", tmp_path / "py" / "run.mcap"
    assert len(read_periods(c)) >= 2000 and read_periods(c).tobytes() == read_periods(py).tobytes()
    assert np.array_equal(read_frames(c), read_frames(py))
    board_c, board_py = (read_topic_messages(path, TOPIC_BOARD) for path in (c, py))
    assert [m.data for m in board_c] == [m.data for m in board_py]
    assert metrics[0] == metrics[1] and "board_isr_time_us" in metrics[0]
