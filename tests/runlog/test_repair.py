"""repair_mcap and `hil mcap-repair` on files cut at many points, and on bad input."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from pmsm_hil.app.cli import mcap_repair
from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.runlog import McapFormatError, RunLogger, read_periods, read_trace, repair_mcap
from pmsm_hil.hil.runlog.reader import MAGIC
from tests.runlog._blocks import period_block, trace_block


@pytest.fixture(scope="module")
def chunked_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A valid file with several chunks (the logger ends a chunk at each flush)."""
    path = tmp_path_factory.mktemp("repair") / "run.mcap"
    with RunLogger(path, metadata={"run": "repair"}, flush_interval_s=0.05) as lg:
        for k in range(0, 4000, 500):
            lg.submit_periods(period_block(k, 500))
            lg.submit_trace(trace_block(k, 500))
            time.sleep(0.12)
    return path


def _count_with_standard_reader(path: Path) -> int:
    with path.open("rb") as f:
        return sum(1 for _ in make_reader(f).iter_messages(topics=["/periods"]))


def test_complete_file_repairs_to_same_content(chunked_file: Path, tmp_path: Path) -> None:
    dst = tmp_path / "out.mcap"
    report = repair_mcap(chunked_file, dst)
    assert report.source_complete and report.chunks >= 4
    assert report.messages_per_topic["/periods"] == 4000
    assert report.metadata_records == 1
    assert _count_with_standard_reader(dst) == 4000


@pytest.mark.parametrize("cut_fraction", [0.3, 0.55, 0.8, 0.97])
def test_truncated_file_recovers_whole_chunks(
    chunked_file: Path, tmp_path: Path, cut_fraction: float
) -> None:
    data = chunked_file.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * cut_fraction)])
    prefix = read_periods(cut)  # tolerant reader works on the cut file directly
    # near the end the cut may fall after the last /periods chunk (the layout depends on flush timing)
    assert 0 < prefix.shape[0] <= 4000
    if cut_fraction <= 0.8:
        assert prefix.shape[0] < 4000
    np.testing.assert_array_equal(prefix["seq"], np.arange(prefix.shape[0]))
    dst = tmp_path / "fixed.mcap"
    report = repair_mcap(cut, dst)
    assert not report.source_complete
    assert report.valid_bytes <= len(data) * cut_fraction and report.lost_bytes >= 0
    assert dst.read_bytes()[-len(MAGIC) :] == MAGIC
    assert _count_with_standard_reader(dst) == prefix.shape[0]
    full = read_periods(chunked_file)
    np.testing.assert_array_equal(read_periods(dst)["i_q"], full["i_q"][: prefix.shape[0]])
    assert read_trace(dst).shape[0] > 0


def test_corrupt_chunk_stops_at_valid_prefix(chunked_file: Path, tmp_path: Path) -> None:
    data = bytearray(chunked_file.read_bytes())
    data[len(data) // 2] ^= 0xFF
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    report = repair_mcap(bad, tmp_path / "fixed.mcap")
    assert 0 < report.messages_per_topic.get("/periods", 0) < 4000
    assert "corrupt" in report.stop_reason or "cut" in report.stop_reason


def test_not_an_mcap_file(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"hello world, not mcap")
    with pytest.raises(McapFormatError, match="bad magic"):
        repair_mcap(junk, tmp_path / "out.mcap")
    with pytest.raises(McapFormatError, match="dst"):
        repair_mcap(junk, junk)


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="hil")
    mcap_repair.add_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(argv)


def test_cli_repairs_cut_file(chunked_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(chunked_file.read_bytes()[: chunked_file.stat().st_size // 2])
    args = _parse(["mcap-repair", str(cut)])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "cut" in out and "/periods" in out
    assert _count_with_standard_reader(tmp_path / "cut.repaired.mcap") > 0
    args = _parse(["mcap-repair", str(cut), "-o", str(tmp_path / "o.mcap")])
    assert mcap_repair.run(args) == 0 and (tmp_path / "o.mcap").is_file()


def test_cli_bad_input_returns_error_without_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["mcap-repair", str(tmp_path / "missing.mcap")]) == 2
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"x" * 100)
    assert main(["mcap-repair", str(junk)]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 2 and all(line.startswith("hil: error: ") for line in lines)
    assert "IN.mcap" in lines[0] and "bad magic" in lines[1] and "Traceback" not in err


def _repaired(chunked_file: Path, out_dir: Path) -> tuple[Path, bytes]:
    """`hil mcap-repair chunked_file -o out_dir/good.mcap`: the output and its bytes."""
    good = out_dir / "good.mcap"
    assert main(["mcap-repair", str(chunked_file), "-o", str(good)]) == 0
    return good, good.read_bytes()


def test_cli_failed_repair_leaves_existing_output_untouched(
    chunked_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good, before = _repaired(chunked_file, tmp_path)
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"x" * 100)
    assert main(["mcap-repair", str(junk), "-o", str(good)]) == 2
    assert good.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.mcap", "junk.mcap"]  # no temporary left
    capsys.readouterr()


def test_cli_refuses_output_onto_its_input(chunked_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = chunked_file.read_bytes()
    assert main(["mcap-repair", str(chunked_file), "-o", str(chunked_file)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hil: error: -o ") and "reads or writes itself" in err
    assert chunked_file.read_bytes() == before


def test_cli_never_replaces_an_existing_output_without_overwrite(
    chunked_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good, before = _repaired(chunked_file, tmp_path)
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(MAGIC)  # a valid start, no message
    assert main(["mcap-repair", str(empty), "-o", str(good)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hil: error: -o ") and "--overwrite" in err and len(err.strip().splitlines()) == 1
    assert good.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.mcap", "good.mcap"]  # no temporary left
    assert main(["mcap-repair", str(chunked_file), "-o", str(good)]) == 2  # as many messages: still refused
    assert good.read_bytes() == before
    notes = tmp_path / "notes.txt"  # not an MCAP file: kept as well
    notes.write_text("my notes\n")
    assert main(["mcap-repair", str(chunked_file), "-o", str(notes)]) == 2
    assert notes.read_text() == "my notes\n"
    err = capsys.readouterr().err
    assert "notes.txt: exists; give --overwrite" in err and len(err.strip().splitlines()) == 2
    assert main(["mcap-repair", str(empty), "-o", str(good), "--overwrite"]) == 0
    assert _count_with_standard_reader(good) == 0
    capsys.readouterr()
