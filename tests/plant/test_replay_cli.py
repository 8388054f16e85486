"""`hil plant replay`: both CSV forms, options, every bad input (clear one-line error, exit 2)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.presets_loader import load_motor

HEADER = ["t", "i_a", "i_b", "i_c", "i_d", "i_q", "torque", "theta_e", "omega_m"]
TS = 100e-6
LEGS_ROWS = ["1,0,0", "1,1,0", "0,1,0", "0,0,0", "1,1,1", "0,1,1", "0,0,1", "1,0,1"]
SEQ_ROWS = ["4,2.5e-5,6,5e-5,7,2.5e-5", "0,0.0001,,,,", "1,4e-5,3,6e-5,,", "2,1e-5,0,0,5,9e-5"]


def _write(tmp_path: Path, name: str, lines: list[str]) -> Path:
    path = tmp_path / name
    path.write_text("".join(f"{line}\n" for line in lines), encoding="utf-8")
    return path


def _replay(tmp_path: Path, input_path: Path, *extra: str, motor: str = "niu2020-ipmsm",
            ts: str = "1e-4") -> tuple[int, Path]:
    out = tmp_path / "out.csv"
    rc = main(["plant", "replay", "--motor", motor, "--rpm", "1500", "--ts", ts,
               "--input", str(input_path), "--output", str(out), *extra])
    return rc, out


def _read(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    return rows[0], np.array([[float(v) for v in row] for row in rows[1:]])


@pytest.mark.parametrize(("header", "rows"), [("sa,sb,sc", LEGS_ROWS), ("s0,t0,s1,t1,s2,t2", SEQ_ROWS)])
def test_both_forms_give_n_plus_one_rows(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                         header: str, rows: list[str]) -> None:
    rc, out = _replay(tmp_path, _write(tmp_path, "in.csv", [header, *rows]))
    assert rc == 0
    assert f"replayed {len(rows)} periods" in capsys.readouterr().out
    head, data = _read(out)
    assert head == HEADER
    assert data.shape == (len(rows) + 1, len(HEADER))
    assert np.allclose(data[:, 0], np.arange(len(rows) + 1) * TS, atol=1e-15)
    assert np.all(data[0, 1:7] == 0.0) and data[0, 7] == 0.0  # row 0: initial state, zero current
    assert np.allclose(data[:, 8], 1500 * 2 * math.pi / 60)
    assert np.abs(data[1:, 1:6]).max() > 0.01  # the commands actually drove current


def test_output_equals_driving_the_plant_directly(tmp_path: Path) -> None:
    rc, out = _replay(tmp_path, _write(tmp_path, "in.csv", ["s0,t0,s1,t1,s2,t2", *SEQ_ROWS]),
                      "--theta0", "0.7", "--set", "rs=3.9")
    assert rc == 0
    _, data = _read(out)
    plant = Plant(load_motor("niu2020-ipmsm", {"rs": 3.9}), TS, DynoMechanics(1500.0), theta0_rad=0.7)
    commands = [([4, 6, 7], [25_000, 50_000, 25_000]), ([0], [100_000]), ([1, 3], [40_000, 60_000]),
                ([2, 0, 5], [10_000, 0, 90_000])]
    expected = []
    for states, durations in [([], []), *commands]:
        if states:
            plant.advance(states, durations)
        s = plant.sample()
        expected.append([s.t, s.i_a, s.i_b, s.i_c, s.i_d, s.i_q, s.torque, s.theta_e, s.omega_m])
    assert np.array_equal(data, np.array(expected))  # repr() round-trips floats exactly


def test_theta0_sets_the_initial_angle(tmp_path: Path) -> None:
    rc, out = _replay(tmp_path, _write(tmp_path, "in.csv", ["sa,sb,sc", "1,0,0"]), "--theta0", "1.25")
    assert rc == 0
    _, data = _read(out)
    assert data[0, 7] == pytest.approx(1.25)
    w_e = 3 * 1500 * 2 * math.pi / 60
    assert data[1, 7] == pytest.approx((1.25 + w_e * TS) % (2 * math.pi))


def test_set_overrides_change_the_result(tmp_path: Path) -> None:
    path = _write(tmp_path, "in.csv", ["sa,sb,sc", "1,0,0", "1,0,0"])
    _, out = _replay(tmp_path, path)
    _, base = _read(out)
    _, out = _replay(tmp_path, path, "--set", "vdc=200", "--set", "lq=0.02")
    _, changed = _read(out)
    assert not np.allclose(base[1:, 1:6], changed[1:, 1:6])
    plant = Plant(load_motor("niu2020-ipmsm", {"vdc": 200.0, "lq": 0.02}), TS, DynoMechanics(1500.0))
    plant.advance([4], [100_000])
    plant.advance([4], [100_000])
    assert changed[2, 5] == plant.sample().i_q


BAD_CSV = [
    ("bad bit value", ["sa,sb,sc", "1,0,0", "1,2,0"], ["row 2", "'sb'", "0 or 1"]),
    ("bit not a number", ["sa,sb,sc", "x,0,0"], ["row 1", "'sa'"]),
    ("wrong column count", ["sa,sb,sc", "1,0"], ["row 1", "expected 3 columns, got 2"]),
    ("wrong column count seq", ["s0,t0,s1,t1", "1,1e-4,2"], ["row 1", "expected 4 columns"]),
    ("unknown header", ["a,b,c", "1,0,0"], ["header", "a,b,c"]),
    ("bad sequence header", ["s0,t0,s2,t2", "1,1e-4,,"], ["header", "s0,t0,s2,t2"]),
    ("state code 9", ["s0,t0", "9,1e-4"], ["row 1", "'s0'", "0..7", "'9'"]),
    ("state code not ascii digit", ["s0,t0", "²,1e-4"], ["row 1", "'s0'", "0..7"]),
    ("negative duration", ["s0,t0,s1,t1", "1,-1e-5,2,1.1e-4"], ["row 1", "'t0'", "≥ 0"]),
    ("durations not summing to Ts", ["s0,t0,s1,t1", "4,1e-4,0,0", "1,5e-5,2,4e-5"],
     ["row 2", "sum to 9e-05 s", "Ts = 0.0001 s"]),
    ("non-numeric duration", ["s0,t0", "3,abc"], ["row 1", "'t0'", "not a number"]),
    ("infinite duration", ["s0,t0", "3,inf"], ["row 1", "'t0'"]),
    ("state without duration", ["s0,t0,s1,t1", "1,1e-4,2,"], ["row 1", "'t1'", "empty"]),
    ("empty file", [], ["empty"]),
]


@pytest.mark.parametrize(("case", "lines", "fragments"), BAD_CSV, ids=[c[0] for c in BAD_CSV])
def test_bad_csv_gives_one_line_error_and_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                 case: str, lines: list[str], fragments: list[str]) -> None:
    rc, out = _replay(tmp_path, _write(tmp_path, "in.csv", lines))
    assert rc == 2, case
    _assert_one_line_error(capsys.readouterr().err, fragments)
    assert not out.exists()


def test_undecodable_bytes_are_a_clear_row_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "in.csv"
    path.write_bytes(b"sa,sb,sc\n\xff\xfe,1,0\n")
    rc, _ = _replay(tmp_path, path)
    assert rc == 2
    _assert_one_line_error(capsys.readouterr().err, ["row 1", "'sa'"])


def test_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc, _ = _replay(tmp_path, tmp_path / "nope.csv")
    assert rc == 2
    _assert_one_line_error(capsys.readouterr().err, ["nope.csv", "No such file"])


BAD_PARAMS = [
    ("unknown preset", ["--motor", "no-such-motor"], ["unknown motor preset 'no-such-motor'"]),
    ("ld negative", ["--set", "ld=-1"], ["'ld'", "> 0"]),
    ("pole pairs fractional", ["--set", "pole_pairs=2.5"], ["'pole_pairs'", "integer"]),
    ("unknown parameter", ["--set", "foo=1"], ["unknown motor parameter 'foo'"]),
    ("set value not a number", ["--set", "rs=abc"], ["--set rs", "not a number"]),
    ("set without equals", ["--set", "rs"], ["NAME=VALUE"]),
    ("ts too small", ["--ts", "1e-7"], ["'ts'", "between"]),
    ("ts not whole ns", ["--ts", "1.00000005e-4"], ["'ts'", "whole number of ns"]),
    ("ts zero", ["--ts", "0"], ["'ts'"]),
]


@pytest.mark.parametrize(("case", "args", "fragments"), BAD_PARAMS, ids=[c[0] for c in BAD_PARAMS])
def test_bad_parameters_give_one_line_error_and_exit_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str, args: list[str],
        fragments: list[str]) -> None:
    path = _write(tmp_path, "in.csv", ["sa,sb,sc", "1,0,0"])
    motor = "niu2020-ipmsm"
    ts = "1e-4"
    rest = list(args)
    if rest[0] == "--motor":
        motor, rest = rest[1], rest[2:]
    elif rest[0] == "--ts":
        ts, rest = rest[1], rest[2:]
    rc, out = _replay(tmp_path, path, *rest, motor=motor, ts=ts)
    assert rc == 2, case
    _assert_one_line_error(capsys.readouterr().err, fragments)
    assert not out.exists()


@pytest.mark.parametrize("ts", ["abc", "nan"])
def test_non_numeric_ts_is_an_argparse_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                   ts: str) -> None:
    path = _write(tmp_path, "in.csv", ["sa,sb,sc", "1,0,0"])
    with pytest.raises(SystemExit) as exc:
        _replay(tmp_path, path, ts=ts)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    what = "a number" if ts == "abc" else "finite"
    assert err.strip().splitlines()[-1].endswith(f"argument --ts: --ts must be {what}, got '{ts}'")


def _assert_one_line_error(err: str, fragments: list[str]) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hil: error: "), err
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
