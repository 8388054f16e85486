"""`hil plant replay` with a dual three-phase motor: leg and sequence forms, output columns, errors."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.plant6 import Plant6
from pmsm_hil.hil.presets_loader import load_motor

HEADER6 = ["t", "i_a1", "i_b1", "i_c1", "i_a2", "i_b2", "i_c2", "i_d", "i_q", "i_x", "i_y", "torque",
           "theta_e", "omega_m"]
MOTOR = "zhang2021-dtpmsm"


def _run(tmp_path: Path, lines: list[str], motor: str = MOTOR) -> tuple[int, Path]:
    src = tmp_path / "in.csv"
    src.write_text("".join(f"{line}\n" for line in lines), encoding="utf-8")
    out = tmp_path / "out.csv"
    rc = main(["plant", "replay", "--motor", motor, "--rpm", "1500", "--ts", "1e-4", "--input", str(src),
               "--output", str(out)])
    return rc, out


def _read(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    return rows[0], np.array([[float(v) for v in row] for row in rows[1:]])


def test_leg_form_matches_driving_plant6_directly(tmp_path: Path) -> None:
    rows = ["1,1,0,1,1,0", "0,0,1,1,0,1", "0,0,0,0,0,0"]  # codes 54 (G1), 13 (V13), 0
    rc, out = _run(tmp_path, ["sa1,sb1,sc1,sa2,sb2,sc2", *rows])
    assert rc == 0
    head, data = _read(out)
    assert head == HEADER6 and data.shape == (4, len(HEADER6))
    plant = Plant6(load_motor(MOTOR), 1e-4, DynoMechanics(1500.0), trace_dt_s=None)
    for code in (54, 13, 0):
        plant.advance([code], [100_000])
    s = plant.sample()
    expected = [s.t, s.i_a, s.i_b, s.i_c, s.i_u, s.i_v, s.i_w, s.i_d, s.i_q, s.i_x, s.i_y, s.torque, s.theta_e,
                s.omega_m]
    assert np.allclose(data[-1], expected, rtol=0, atol=1e-12)
    assert np.abs(data[1:, 9:11]).max() > 1.0  # x-y current was driven


def test_sequence_form_accepts_six_bit_codes(tmp_path: Path) -> None:
    rc, out = _run(tmp_path, ["s0,t0,s1,t1", "27,7.32e-5,10,2.68e-5", "63,1e-4,,"])
    assert rc == 0
    _, data = _read(out)
    assert data.shape == (3, len(HEADER6))


@pytest.mark.parametrize(("lines", "motor", "needle"), [
    (["sa,sb,sc", "1,0,0"], MOTOR, "sa1,sb1,sc1,sa2,sb2,sc2"),
    (["sa1,sb1,sc1,sa2,sb2,sc2", "1,0,0,0,0,0"], "niu2020-ipmsm", "sa,sb,sc"),
    (["s0,t0", "64,1e-4"], MOTOR, "0..63"),
    (["s0,t0", "9,1e-4"], "niu2020-ipmsm", "0..7"),
    (["sa1,sb1,sc1,sa2,sb2,sc2", "1,0,2,0,0,0"], MOTOR, "sc1"),
])
def test_bad_input_is_a_one_line_error(tmp_path: Path, capsys: pytest.CaptureFixture[str], lines: list[str],
                                       motor: str, needle: str) -> None:
    rc, _ = _run(tmp_path, lines, motor)
    assert rc == 2
    assert needle in capsys.readouterr().err
