"""`hil mcap export` (hil/runlog/can_log.py): a run's /frames written through python-can's log writers and read
back by python-can's readers with the same frames and virtual times."""

from __future__ import annotations

from pathlib import Path

import can
import numpy as np
import pytest
from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.runlog import read_frames


@pytest.fixture(scope="module")
def run_mcap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("export") / "run"
    assert main(["run", "--duration", "0.01", "--settle", "0.002", "--out", str(out)]) == 0
    return out / "run.mcap"


def _same(frames: np.ndarray, msgs: list[can.Message]) -> None:
    assert len(msgs) == len(frames) > 100
    for fr, msg in zip(frames, msgs, strict=True):
        n = int(fr["length"])
        assert (msg.arbitration_id, bytes(msg.data), msg.is_fd, msg.is_rx) == (
            int(fr["arbitration_id"]), bytes(fr["data"][:n]), bool(fr["is_fd"]), int(fr["direction"]) == 1)
        assert msg.timestamp == pytest.approx(float(fr["t"]), abs=1e-6)  # virtual time, µs resolution


def test_asc_export_is_read_back_by_ascreader_with_the_same_frames(run_mcap: Path, tmp_path: Path) -> None:
    out = tmp_path / "run.asc"
    assert main(["mcap", "export", str(run_mcap), "--format", "asc", "-o", str(out)]) == 0
    frames = read_frames(run_mcap)
    assert {int(d) for d in frames["direction"]} == {0, 1}  # Commands and Measurements both
    _same(frames, list(can.ASCReader(out)))


@pytest.mark.parametrize(("fmt", "reader"), [("candump", can.CanutilsLogReader), ("blf", can.BLFReader)])
def test_candump_and_blf_exports_read_back(run_mcap: Path, tmp_path: Path, fmt: str, reader: type) -> None:
    out = tmp_path / f"run.{fmt}"
    assert main(["mcap", "export", str(run_mcap), "--format", fmt, "-o", str(out)]) == 0
    msgs = list(reader(out))
    frames = read_frames(run_mcap)
    if fmt == "candump":  # candump -L keeps no Tx/Rx distinction python-can reads back
        for m, fr in zip(msgs, frames, strict=True):
            m.is_rx = int(fr["direction"]) == 1
    _same(frames, msgs)


def test_csv_export_has_a_row_per_frame(run_mcap: Path, tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    assert main(["mcap", "export", str(run_mcap), "--format", "csv", "-o", str(out)]) == 0
    msgs = list(can.CSVReader(out))
    frames = read_frames(run_mcap)
    assert [m.arbitration_id for m in msgs] == [int(i) for i in frames["arbitration_id"]]


def test_bad_input_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["mcap", "export", str(tmp_path / "none.mcap"), "--format", "asc", "-o", str(tmp_path / "x")]) != 0
    err = capsys.readouterr().err
    assert "none.mcap" in err and "Traceback" not in err
