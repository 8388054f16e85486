"""A full disk (here: a file size limit on the logger process) ends the run with one clear line and an MCAP
that is valid up to what fitted, or none, said so."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.runlog import RunLogger, read_periods
from pmsm_hil.hil.runlog import logger as logger_module
from pmsm_hil.hil.runlog.salvage import end_after_last_record, last_record_end
from tests.runlog._blocks import period_block
from tests.runlog._fsize_worker import limited_worker


def _standard_periods(path: Path) -> np.ndarray:
    """/periods seq of `path` read by the mcap library (it needs a valid file: magic, records, footer)."""
    with path.open("rb") as f:
        return np.array([m.sequence for _, _, m in make_reader(f).iter_messages(topics=["/periods"])])


@pytest.fixture
def limited_logger(monkeypatch: pytest.MonkeyPatch) -> pytest.MonkeyPatch:
    monkeypatch.setattr(logger_module, "run_worker", limited_worker)
    return monkeypatch


def test_a_run_on_a_full_disk_keeps_a_valid_mcap(tmp_path: Path, limited_logger: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    limited_logger.setenv("HIL_TEST_FSIZE", "6000000")  # room for a chunk or two (~3 MB each, lz4)
    out = tmp_path / "r"
    assert main(["run", "--out", str(out), "--duration", "30", "--settle", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    mcap = out / "run.mcap"
    seq = _standard_periods(mcap)
    assert err[0].startswith(f"hil: error: run logger: cannot write {mcap} (File too large); the file is kept as "
                             f"a valid MCAP up to its last complete chunk: the first {seq.shape[0]} periods of the ")
    assert mcap.stat().st_size <= 6_000_000
    assert 1000 <= seq.shape[0] < 300_000 and (seq == np.arange(seq.shape[0])).all()
    assert read_periods(mcap).shape[0] == seq.shape[0]
    assert not (out / "metrics.json").exists()  # the run stopped (safe stop) at the logger's error


def test_a_run_where_nothing_fits_removes_its_mcap(tmp_path: Path, limited_logger: pytest.MonkeyPatch,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    limited_logger.setenv("HIL_TEST_FSIZE", "10")
    out = tmp_path / "r"
    assert main(["run", "--out", str(out), "--duration", "0.5", "--settle", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"hil: error: run logger: cannot write {out / 'run.mcap'} (File too large); nothing of the log "
                   "fitted: the file is removed"]
    assert not (out / "run.mcap").exists()


def test_a_logger_on_a_full_disk_says_so_on_close(tmp_path: Path, limited_logger: pytest.MonkeyPatch) -> None:
    limited_logger.setenv("HIL_TEST_FSIZE", "1000000")
    path = tmp_path / "run.mcap"
    lg = RunLogger(path, metadata={}, flush_interval_s=0.02, ring_bytes=1 << 20)
    said = "valid MCAP up to its last complete chunk: the first [1-9][0-9]* periods of the"
    with pytest.raises(logger_module.LoggerDiedError, match=said):  # a submit finds the logger gone
        for k in range(0, 200_000, 100):  # random values: ~200 B a period, chunks of ~0.02 s
            lg.submit_periods(period_block(k, 100))
            time.sleep(0.005)
    with pytest.raises(logger_module.LoggerDiedError, match=said):
        lg.close()
    lg.close()  # idempotent after the error
    seq = _standard_periods(path)
    assert seq.shape[0] > 0 and (seq == np.arange(seq.shape[0])).all()


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A logged file of 6000 periods in several chunks (flushed every 10 ms, blocks 30 ms apart), shared by the
    tests that cut copies of it (read only)."""
    path = tmp_path_factory.mktemp("whole") / "whole.mcap"
    with RunLogger(path, metadata={"run": "cut"}, flush_interval_s=0.01) as lg:
        for k in range(0, 6000, 500):
            lg.submit_periods(period_block(k, 500))
            time.sleep(0.03)
    return path


@pytest.mark.parametrize("fraction", [0.3, 0.55, 0.8, 0.999])
def test_a_cut_file_ends_as_a_valid_mcap(tmp_path: Path, whole: Path, fraction: float) -> None:
    cut = tmp_path / "cut.mcap"
    shutil.copyfile(whole, cut)
    with cut.open("r+b") as f:
        f.truncate(int(whole.stat().st_size * fraction))
    recovered = read_periods(cut).shape[0]  # the tolerant reader on the cut file
    kept = end_after_last_record(cut, channel=1)  # /periods: the sink's first channel
    assert kept == last_record_end(cut, channel=1) and kept.bytes > 0
    seq = _standard_periods(cut)
    assert seq.shape[0] == recovered == kept.messages and (seq == np.arange(recovered)).all()


def test_nothing_to_keep(tmp_path: Path) -> None:
    stub = tmp_path / "x.mcap"
    stub.write_bytes(b"\x89MCAP0\r\n\x01")  # the magic and a cut Header record
    assert end_after_last_record(stub).bytes == 0 and stub.read_bytes() == b"\x89MCAP0\r\n\x01"


def _chunk_ends(path: Path) -> list[int]:
    """File offsets where each Chunk record of `path` ends (record headers only)."""
    import struct

    from mcap.opcode import Opcode

    data, pos, ends = path.read_bytes(), 8, []
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, pos)
        pos += 9 + length
        if opcode == Opcode.CHUNK:
            ends.append(pos)
        if opcode == Opcode.DATA_END:
            break
    return ends


@pytest.mark.parametrize("extra", [0, 5])
def test_a_file_cut_before_its_last_message_index_counts_what_it_holds(tmp_path: Path, whole: Path,
                                                                      extra: int) -> None:
    """A disk that fills right after a chunk (its Message Index records cut or missing): the count said is the
    periods the file holds, not those the surviving indexes list (never "the first 0 periods" of 16 000)."""
    ends = _chunk_ends(whole)
    assert len(ends) >= 2
    held_at = []
    for end in ends:  # the logger's timer may close a chunk before the first periods arrive: one without periods
        cut = tmp_path / f"cut{end}.mcap"
        cut.write_bytes(whole.read_bytes()[:end + extra])
        held = read_periods(cut).shape[0]
        kept = end_after_last_record(cut, channel=1)
        assert kept.messages == held == _standard_periods(cut).shape[0], end
        held_at.append(held)
    assert held_at == sorted(held_at) and 0 < held_at[-1] <= 6000, held_at
