"""`hil mcap export` (src/pmsm_hil/hil/runlog/can_log.py): a run's /frames written through python-can's log writers and
read back by python-can's readers with the same frames and virtual times."""

from __future__ import annotations

from pathlib import Path

import can
import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.runlog import read_frames
from pmsm_hil.hil.runlog.can_log import FLAGS, FORMATS, KEEPS

_EXPORT_SUFFIX = {"candump": ".log", "asc": ".asc", "blf": ".blf", "csv": ".csv"}


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


def _flags(msg: can.Message) -> dict[str, bool]:
    return {"fd": msg.is_fd, "brs": msg.bitrate_switch, "esi": msg.error_state_indicator, "direction": msg.is_rx}


@pytest.mark.parametrize("fmt", sorted(FORMATS))
def test_each_format_keeps_the_flags_the_docs_name_and_loses_the_others(fmt: str, tmp_path: Path) -> None:
    """`KEEPS` (docs/logging.md, "What each format keeps") against the installed python-can: frames with every
    combination of FD, bit-rate switch, error state indicator and direction through the format's writer and reader."""
    writer_class, channel = FORMATS[fmt]
    sent = [can.Message(timestamp=0.5 + k * 1e-3, arbitration_id=0x108 + k, is_extended_id=False, is_fd=fd,
                        bitrate_switch=fd and brs, error_state_indicator=fd and esi, is_rx=rx, channel=channel,
                        data=bytes(range(12 if fd else 8)))
            for k, (fd, brs, esi, rx) in enumerate((fd, brs, esi, rx) for fd in (False, True) for brs in (False, True)
                                                   for esi in (False, True) for rx in (False, True))]
    path = tmp_path / f"flags{_EXPORT_SUFFIX[fmt]}"
    writer = writer_class(path)
    for msg in sent:
        writer.on_message_received(msg)
    writer.stop()
    back = list(can.LogReader(path))
    assert [(m.arbitration_id, bytes(m.data)) for m in back] == [(m.arbitration_id, bytes(m.data)) for m in sent]
    for flag in FLAGS:
        kept = [_flags(m)[flag] for m in back] == [_flags(m)[flag] for m in sent]
        assert kept == (flag in KEEPS[fmt]), f"{fmt} {'loses' if not kept else 'keeps'} {flag}"


@pytest.mark.parametrize("fmt", sorted(FORMATS))
def test_an_export_keeps_fd_and_direction_where_the_format_can(run_mcap: Path, tmp_path: Path, fmt: str) -> None:
    """The run's CAN FD frames (sent with the bit-rate switch) and both directions, read back by python-can: kept by
    candump, ASC and BLF; python-can's CSV reads every frame as a received classic one (docs/logging.md)."""
    out = tmp_path / f"run{_EXPORT_SUFFIX[fmt]}"
    assert main(["mcap", "export", str(run_mcap), "--format", fmt, "-o", str(out)]) == 0
    frames = read_frames(run_mcap)
    assert frames["is_fd"].any() and {int(d) for d in frames["direction"]} == {0, 1}
    back = list(can.LogReader(out))
    assert len(back) == len(frames)
    logged = [{"fd": bool(fr["is_fd"]), "brs": bool(fr["is_fd"]), "esi": False, "direction": int(fr["direction"]) == 1}
              for fr in frames]
    if KEEPS[fmt] == FLAGS:
        assert [_flags(m) for m in back] == logged
    else:
        assert not any(m.is_fd or m.bitrate_switch for m in back) and all(m.is_rx for m in back)


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


def _one_line(capsys: pytest.CaptureFixture[str], *needles: str) -> None:
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and err.startswith("hil: error: ") and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err


def _corrupt_copies(good: Path, folder: Path) -> dict[str, Path]:
    """`good` truncated at half its size, with garbage bytes instead of its middle third, and with bit flips
    spread over it (after its first 64 bytes)."""
    data = good.read_bytes()
    n = len(data)
    flipped = bytearray(data)
    for i in range(64, n, max(1, n // 16)):
        flipped[i] ^= 0x24
    variants = {"truncated": data[: n // 2],
                "garbage": data[: n // 3] + bytes((7 * i + 3) % 251 for i in range(n // 3)) + data[2 * n // 3:],
                "bitflips": bytes(flipped)}
    out = {}
    for name, content in variants.items():
        path = folder / f"{name}{good.suffix}"
        path.write_bytes(content)
        out[name] = path
    return out


def _cut_inside_the_first_chunk(good: Path, folder: Path) -> Path:
    """`good` up to the middle of its first Chunk record (MCAP: magic, then records of opcode, u64 length, body)."""
    data = good.read_bytes()
    pos = 8
    while data[pos] != 0x06:  # Chunk
        pos += 9 + int.from_bytes(data[pos + 1:pos + 9], "little")
    cut = folder / "cut-in-chunk.mcap"
    cut.write_bytes(data[: pos + 9 + int.from_bytes(data[pos + 1:pos + 9], "little") // 2])
    return cut


def test_export_refuses_a_corrupt_run_log_and_writes_nothing(run_mcap: Path, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    for kind, bad in _corrupt_copies(run_mcap, tmp_path).items():
        out = tmp_path / f"{kind}.log"
        assert main(["mcap", "export", str(bad), "--format", "candump", "-o", str(out)]) == 2, kind
        _one_line(capsys, f"RUN.mcap {bad}: cut or corrupt after", "hil mcap-repair")
        assert not out.exists()
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap at all" * 10)
    assert main(["mcap", "export", str(junk), "--format", "csv", "-o", str(tmp_path / "j.csv")]) == 2
    _one_line(capsys, "not an MCAP file")
    # cut inside the first chunk: the prefix `hil mcap-repair` recovers holds no channel, and says so (the logger
    # ends a chunk every second of wall time: on a busy machine even this short run has more than one)
    repaired = tmp_path / "repaired.mcap"
    assert main(["mcap-repair", str(_cut_inside_the_first_chunk(run_mcap, tmp_path)), "-o", str(repaired)]) == 0
    capsys.readouterr()
    assert main(["mcap", "export", str(repaired), "--format", "candump", "-o", str(tmp_path / "r.log")]) == 2
    _one_line(capsys, "has no /frames channel")


def test_export_never_replaces_a_file_without_overwrite(run_mcap: Path, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "other_run.log"
    out.write_text("another run's capture\n")
    assert main(["mcap", "export", str(run_mcap), "--format", "candump", "-o", str(out)]) == 2
    _one_line(capsys, f"-o {out}: exists; give --overwrite")
    assert out.read_text() == "another run's capture\n"
    assert main(["mcap", "export", str(run_mcap), "--format", "candump", "-o", str(out), "--overwrite"]) == 0
    assert len(list(can.CanutilsLogReader(out))) == len(read_frames(run_mcap))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other_run.log"]  # no temporary file left


def _commands(run_mcap: Path) -> list[tuple[tuple[int, ...], tuple[int, ...]]]:
    from pmsm_hil.protocol.codec import FrameDecoder
    from pmsm_hil.protocol.frame import Frame
    from pmsm_hil.protocol.messages import Command

    dec = FrameDecoder()
    out = []
    for fr in read_frames(run_mcap):
        msg = dec.feed(Frame(int(fr["arbitration_id"]), bytes(fr["data"][:int(fr["length"])]), bool(fr["is_fd"])))
        if isinstance(msg, Command):
            out.append(msg.expanded())
    return out


@pytest.mark.parametrize("fmt", ["asc", "candump"])
def test_hil_replay_of_an_exported_log_drives_the_plant_with_the_runs_commands(
        run_mcap: Path, tmp_path: Path, fmt: str) -> None:
    """The CAN log's Commands through the plant give the same rows as the same Commands written as a replay CSV
    (sequence form) through `hil plant replay`, after the zero vector of the loop's period 0 (Command k drives
    period k + 1)."""
    log = tmp_path / ("run.asc" if fmt == "asc" else "run.log")
    assert main(["mcap", "export", str(run_mcap), "--format", fmt, "-o", str(log)]) == 0
    cmds = _commands(run_mcap)
    slots = max(len(s) for s, _ in cmds)
    csv_in = tmp_path / "commands.csv"
    rows = [",".join(f"s{k},t{k}" for k in range(slots)), ",".join(["0", "1e-4"] + [""] * (2 * slots - 2))]
    for states, durs in cmds:
        cells = [f"{s},{d * 1e-9!r}" for s, d in zip(states, durs, strict=True)] + [","] * (slots - len(states))
        rows.append(",".join(cells))
    csv_in.write_text("\n".join(rows) + "\n")
    common = ["--rpm", "1000", "--ts", "1e-4"]
    assert main(["replay", str(log), *common, "--output", str(tmp_path / "from_log.csv")]) == 0
    assert main(["plant", "replay", "--motor", "niu2020-ipmsm", *common, "--input", str(csv_in),
                 "--output", str(tmp_path / "from_csv.csv")]) == 0
    from_log = (tmp_path / "from_log.csv").read_text().splitlines()
    assert len(from_log) == len(cmds) + 3 > 50  # header, the initial state, period 0, one row per Command
    assert from_log == (tmp_path / "from_csv.csv").read_text().splitlines()


def test_hil_replay_of_a_can_log_needs_the_plant_options(run_mcap: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "run.asc"
    assert main(["mcap", "export", str(run_mcap), "--format", "asc", "-o", str(log)]) == 0
    assert main(["replay", str(log), "--ts", "1e-4", "--output", str(tmp_path / "o.csv")]) != 0
    assert "--rpm is required" in capsys.readouterr().err
    assert main(["replay", str(log), "--rpm", "0", "--ts", "2e-4", "--output", str(tmp_path / "o.csv")]) != 0
    assert "expected Ts = 200000 ns (--ts)" in capsys.readouterr().err


@pytest.mark.parametrize("fmt", ["candump", "asc", "blf", "csv"])
def test_hil_replay_refuses_a_corrupt_can_log_in_one_line(run_mcap: Path, tmp_path: Path, fmt: str,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    good = tmp_path / f"run{_EXPORT_SUFFIX[fmt]}"
    assert main(["mcap", "export", str(run_mcap), "--format", fmt, "-o", str(good)]) == 0
    common = ["--rpm", "1000", "--ts", "1e-4"]
    assert main(["replay", str(good), *common, "--output", str(tmp_path / "good.csv")]) == 0
    capsys.readouterr()
    for kind, bad in _corrupt_copies(good, tmp_path).items():
        out = tmp_path / f"{kind}.out.csv"
        assert main(["replay", str(bad), *common, "--output", str(out)]) == 2, kind
        _one_line(capsys, f"CAN log {bad}: ")
        assert not out.exists()


@pytest.mark.parametrize("change", ["reversed", "duplicated", "repeated line", "lost Command"])
def test_hil_replay_refuses_a_reordered_capture_naming_the_seq(run_mcap: Path, tmp_path: Path, change: str,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    good = tmp_path / "run.log"
    assert main(["mcap", "export", str(run_mcap), "--format", "candump", "-o", str(good)]) == 0
    capsys.readouterr()
    lines = good.read_text().splitlines()
    cmd_lines = [i for i, line in enumerate(lines) if " can0 " in line and line.split()[2].startswith(_cmd_ids_hex())]
    k = cmd_lines[len(cmd_lines) // 2]
    edited = {"reversed": lines[::-1], "duplicated": lines + lines,
              "repeated line": [*lines[:k + 1], lines[k], *lines[k + 1:]],
              "lost Command": [line for i, line in enumerate(lines) if i not in cmd_lines[10:13]]}[change]
    bad = tmp_path / "bad.log"
    bad.write_text("\n".join(edited) + "\n")
    assert main(["replay", str(bad), "--rpm", "1000", "--ts", "1e-4", "--output", str(tmp_path / "o.csv")]) == 2
    needle = {"reversed": "goes back", "duplicated": "goes back", "repeated line": "appears twice",
              "lost Command": "missing"}[change]
    _one_line(capsys, "Command seq ", needle)
    assert not (tmp_path / "o.csv").exists()


def _cmd_ids_hex() -> tuple[str, ...]:
    """candump -L prefixes of the Command frames (classic first part, CAN FD)."""
    from pmsm_hil.protocol.codec import L_CMD_A, L_CMD_FD

    return tuple(f"{lay.frame_id:03X}#" for lay in (L_CMD_A, L_CMD_FD))
