"""`hil run` command line: JSON contract, config files and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main

REQUIRED_KEYS = {
    "periods", "sim_time_s", "wall_time_s", "loop_rate_hz", "torque_mean_nm", "torque_ripple_rms_nm",
    "torque_ripple_pp_nm", "speed_mean_rpm", "current_thd_pct", "current_thd_total_pct", "current_fundamental_a",
    "switching_freq_khz", "exec_time_us", "candidates_evaluated_mean", "narrow_pulses", "deadline_misses", "link",
}


def test_run_writes_json_with_contract_keys(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "m.json"
    rc = main(["run", "--duration", "0.03", "--settle", "0.02", "--no-log", "--json", str(out)])
    assert rc == 0
    m = json.loads(out.read_text())
    assert set(m) >= REQUIRED_KEYS
    assert set(m["exec_time_us"]) >= {"median", "p99", "max"}
    assert set(m["link"]) >= {"frames_tx", "frames_rx", "crc_errors", "lost", "late"}
    assert m["periods"] == 300
    assert "torque mean" in capsys.readouterr().out


def test_run_logs_mcap_and_metrics_to_out_dir(tmp_path: Path) -> None:
    rc = main(["run", "--duration", "0.02", "--settle", "0", "--out", str(tmp_path / "r")])
    assert rc == 0
    assert (tmp_path / "r" / "run.mcap").stat().st_size > 1000
    assert json.loads((tmp_path / "r" / "metrics.json").read_text())["periods"] == 200


def test_config_file_is_used_and_cli_wins(tmp_path: Path) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text('speed = 1000.0\nload = 3.0\nduration = 0.02\nsettle = 0.02\nno_log = true\n'
                   '[set]\nvdc = 300.0\n')
    out = tmp_path / "m.json"
    assert main(["run", "--config", str(cfg), "--load", "2.0", "--json", str(out)]) == 0
    m = json.loads(out.read_text())
    assert m["speed_ref_rpm"] == 1000.0 and m["load_nm"] == 2.0


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--controller", "nope"], "unknown controller 'nope'"),
        (["--set", "ld=-1"], "'ld' must be > 0"),
        (["--set", "zz=1"], "unknown motor parameter 'zz'"),
        (["--param", "bogus=1"], "unknown controller parameter 'bogus'"),
        (["--param", "ld=-1"], "--param ld=-1.0: the controller's model would be singular"),
        (["--param", "rs=-1"], "target rejected parameter 'rs'"),
        (["--scenario", "nope"], "unknown scenario 'nope'"),
        (["--motor", "nope"], "unknown motor preset 'nope'"),
        (["--ts", "3e-6"], "--ts must be between"),
        (["--link", "nosuchbus:0"], "nosuchbus"),
        (["--controller", "mptc1"], "controller 'mptc1' needs a six-phase motor"),
        (["--motor", "zhang2021-dtpmsm", "--controller", "mpcc"], "controller 'mpcc' needs a three-phase motor"),
    ],
)
def test_bad_input_gives_one_line_error(argv: list[str], needle: str, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["run", "--no-log", "--duration", "0.01", "--settle", "0", *argv])
    err = capsys.readouterr().err
    assert rc == 2
    assert needle in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_bad_config_file_names_the_key(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text("speeed = 3\n")
    assert main(["run", "--config", str(cfg)]) == 2
    assert "unknown key(s) speeed" in capsys.readouterr().err
