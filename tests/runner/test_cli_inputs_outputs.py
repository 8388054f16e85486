"""Inputs and outputs at the command line: every bad input is one line naming the field, outputs are
written whole or not at all and never onto an input, `--out` never mixes runs, the run log records the
configuration and its set-up frames, and the messages and help are the same everywhere."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import build_parser, main
from pmsm_hil.app.cli.run import config_schema
from pmsm_hil.hil.runlog.reader import read_frames, read_metadata
from pmsm_hil.protocol.ids import CONTROLLER_NAMES
from pmsm_hil.protocol.links import LINK_KINDS

SHORT = ["--duration", "0.01", "--settle", "0"]


def _one_line_error(capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith("hil: error: "), err
    for needle in needles:
        assert needle in err, err
    return err


def _refused_onto(capsys: pytest.CaptureFixture[str], target: Path, argv: list[str], option: str) -> None:
    """`hil ARGV` writing onto `target`, a file it reads or writes itself: exit 2, one line naming `option`, the
    file unchanged."""
    before = target.read_bytes()
    capsys.readouterr()
    assert main(argv) == 2
    _one_line_error(capsys, f"{option} {target}: names a file this command reads or writes itself")
    assert target.read_bytes() == before


# input errors
@pytest.mark.parametrize(("text", "needles"), [
    ('speed = "fast"\n', ["'speed' must be a number", "'fast'"]),
    ('duration = "long"\n', ["'duration' must be a number", "'long'"]),
    ('no_log = "yes"\n', ["'no_log' must be a TOML boolean", "'yes'"]),
    ('no_log = "false"\n', ["'no_log' must be a TOML boolean", "'false'"]),
    ("log_trace = 1\n", ["'log_trace' must be a TOML boolean"]),
    ("seed = 1.5\n", ["'seed' must be an integer"]),
    ("duration = -1\n", ["'duration' must be > 0"]),
    ('mode = "fast"\n', ["'mode' must be one of lockstep, realtime"]),
    ("controller = 3\n", ["'controller' must be a string"]),
    ("[set]\nvdc = true\n", ["'set.vdc' must be a number"]),
    ('set = "vdc=300"\n', ["'set' must be a table"]),
    ("speeed = 3\n", ["unknown key(s) speeed"]),
])
def test_config_values_are_checked_against_the_options(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                        text: str, needles: list[str]) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text(text, encoding="utf-8")
    assert main(["run", "--config", str(cfg), "--no-log", *SHORT]) == 2
    _one_line_error(capsys, f"config file {cfg}", *needles)


def test_config_schema_is_derived_from_the_options() -> None:
    schema = config_schema()
    run = next(a for a in build_parser()._actions if a.dest == "command").choices["run"]  # type: ignore[union-attr]
    longs = {o[2:].replace("-", "_") for a in run._actions for o in a.option_strings if o.startswith("--")}
    # the terminal's options are not run options: the live dashboard's (--rerun*) and the status line's (--quiet);
    # nor is where the run happens (--place, --coordinator: a labgrid lease around the run that sets its link)
    terminal = {"help", "config", "debug", "quiet", "place", "coordinator"}
    assert set(schema) == longs - terminal - {k for k in longs if k.startswith("rerun")}
    assert schema["no_log"].kind == "flag" and schema["speed"].kind == "number" and schema["set"].kind == "table"


def test_config_booleans_json_and_overwrite_are_applied(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run_dir = tmp_path / "r"
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'duration = 0.01\nsettle = 0.0\nout = "{run_dir}"\njson = "{tmp_path / "m.json"}"\n'
                   "overwrite = true\nlog_trace = false\n", encoding="utf-8")
    assert main(["run", "--config", str(cfg)]) == 0
    assert main(["run", "--config", str(cfg)]) == 0  # overwrite = true from the file
    assert json.loads((tmp_path / "m.json").read_text())["periods"] == 100
    capsys.readouterr()


@pytest.mark.parametrize("option", ["--config", "--motor", "--scenario"])
def test_non_utf8_toml_names_the_file(tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_bytes("name = 'caf\u00e9'\n".encode("latin-1"))
    assert main(["run", option, str(bad), "--no-log", *SHORT]) == 2
    label = {"--config": "config file", "--motor": "motor file", "--scenario": "scenario file"}[option]
    _one_line_error(capsys, f"{label} {bad}: not UTF-8 text (byte 0xe9 on line 1)")


@pytest.mark.parametrize(("argv", "needles"), [
    (["--speed", "1e308"], ["--speed: 1e+308 rpm", "speed_trip_rpm = 3000 rpm"]),
    (["--speed", "-3000"], ["--speed: -3000 rpm"]),
    (["--duration", "1e308"], ["--duration: ", "more than the 4294967295 a run can count"]),
    (["--duration", "1e6"], ["--duration: 1e+06 s of run", "1e+10 periods", "at most ≈ 4.295e+05 s"]),
    (["--link", "can,bitrate=0"], ["bitrate must be a positive whole number of bit/s, got 0"]),
    (["--link", "serial:pty,baudrate=fast"], ["baudrate must be a positive whole number"]),
])
def test_bounds_name_the_option(capsys: pytest.CaptureFixture[str], argv: list[str], needles: list[str]) -> None:
    assert main(["run", "--no-log", "--settle", "0", *argv]) == 2
    _one_line_error(capsys, *needles)


def test_config_speed_bound_names_the_key(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text("speed = 1e308\n", encoding="utf-8")
    assert main(["run", "--config", str(cfg), "--no-log"]) == 2
    _one_line_error(capsys, f"config file {cfg}: 'speed': 1e+308 rpm")


def test_out_that_is_a_file_or_cannot_be_created(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a_file = tmp_path / "f"
    a_file.write_text("x")
    assert main(["run", "--out", str(a_file), *SHORT]) == 2
    _one_line_error(capsys, f"--out {a_file}: exists and is not a directory")
    assert main(["run", "--out", str(a_file / "sub"), *SHORT]) == 2
    _one_line_error(capsys, f"--out {a_file / 'sub'}: cannot create the directory")
    assert not (a_file / "sub").exists() and a_file.read_text() == "x"


# outputs
def test_out_of_an_existing_run_is_refused_unless_overwrite(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    run_dir = tmp_path / "r"
    assert main(["run", "--out", str(run_dir), "--duration", "0.02", "--settle", "0"]) == 0
    old = {name: (run_dir / name).read_bytes() for name in ("run.mcap", "metrics.json")}
    capsys.readouterr()
    assert main(["run", "--out", str(run_dir), *SHORT]) == 2
    _one_line_error(capsys, f"--out {run_dir}: holds an earlier output (run.mcap, metrics.json)", "--overwrite")
    assert {name: (run_dir / name).read_bytes() for name in old} == old
    (run_dir / "notes.txt").write_text("mine")
    assert main(["run", "--out", str(run_dir), "--overwrite", *SHORT]) == 0
    assert json.loads((run_dir / "metrics.json").read_text())["periods"] == 100  # the new run, not the old 200
    assert sorted(p.name for p in run_dir.iterdir()) == ["metrics.json", "notes.txt", "run.mcap"]


def test_json_onto_an_input_or_the_run_log_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text("speed = 1000.0\n", encoding="utf-8")
    assert main(["run", "--config", str(cfg), "--json", str(cfg), "--no-log", *SHORT]) == 2
    _one_line_error(capsys, f"--json {cfg}: names a file this command reads or writes itself")
    assert cfg.read_text() == "speed = 1000.0\n"
    run_dir = tmp_path / "r"
    assert main(["run", "--out", str(run_dir), "--json", str(run_dir / "run.mcap"), *SHORT]) == 2
    _one_line_error(capsys, "--json")
    assert not run_dir.exists()


def test_report_never_writes_onto_a_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run_dir = tmp_path / "r"
    assert main(["run", "--out", str(run_dir), "--duration", "0.02", "--settle", "0"]) == 0
    mcap = run_dir / "run.mcap"
    _refused_onto(capsys, mcap, ["report", str(run_dir), "-o", str(mcap)], "-o")
    metrics = json.loads((run_dir / "metrics.json").read_text())
    (run_dir / "metrics.json").write_text(json.dumps({**metrics, "periods": "many"}))
    good = tmp_path / "good.html"
    good.write_text("previous report")
    assert main(["report", str(run_dir), "-o", str(good)]) == 2  # another report: never replaced unasked
    _one_line_error(capsys, f"-o {good}: exists; give --overwrite to replace it")
    assert main(["report", str(run_dir), "-o", str(good), "--overwrite"]) == 2
    _one_line_error(capsys, "metrics.json: 'periods' must be a whole number ≥ 0, got 'many'")
    assert good.read_text() == "previous report"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.html", "r"]  # no temporary file left


def test_rerun_save_onto_the_replayed_log_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run_dir = tmp_path / "r"
    assert main(["run", "--out", str(run_dir), *SHORT]) == 0
    mcap = run_dir / "run.mcap"
    _refused_onto(capsys, mcap, ["replay", str(mcap), "--rerun-save", str(mcap)], "--rerun-save")


def _replay(tmp_path: Path, rows: list[str], *extra: str, rpm: str = "1500") -> int:
    src = tmp_path / "in.csv"
    src.write_text("".join(f"{r}\n" for r in rows), encoding="utf-8")
    return main(["plant", "replay", "--motor", "niu2020-ipmsm", "--rpm", rpm, "--ts", "1e-4", "--input", str(src),
                 "--output", str(tmp_path / "out.csv"), *extra])


@pytest.mark.parametrize(("rows", "rpm", "needles"), [
    (["sa,sb,sc"], "1500", ["no command rows after the header"]),
    (["sa,sb,sc", "1,0,0"], "1e308", ["row 1: the plant state is not finite", "--rpm 1e+308"]),
    (["s0,t0", "0,1e308"], "1500", ["row 1, column 't0': duration 1e308 s is longer than Ts"]),
])
def test_replay_without_valid_output_leaves_the_old_one(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                        rows: list[str], rpm: str, needles: list[str]) -> None:
    out = tmp_path / "out.csv"
    out.write_text("previous output\n")
    assert _replay(tmp_path, rows, rpm=rpm) == 2
    _one_line_error(capsys, *needles)
    assert out.read_text() == "previous output\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv", "out.csv"]


def test_replay_output_onto_its_input_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "in.csv"
    src.write_text("sa,sb,sc\n1,0,0\n", encoding="utf-8")
    assert main(["plant", "replay", "--motor", "niu2020-ipmsm", "--rpm", "1500", "--ts", "1e-4",
                 "--input", str(src), "--output", str(tmp_path / "." / "in.csv")]) == 2
    _one_line_error(capsys, "--output", "reads or writes itself")
    assert src.read_text() == "sa,sb,sc\n1,0,0\n"


# the log records the configuration
def test_log_records_the_run_configuration_and_setup_frames(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    run_dir = tmp_path / "r"
    assert main(["run", "--out", str(run_dir), "--set", "rs=0.9", "--param", "speed_kp=0.7", "--seed", "5",
                 "--noise", "0.01", *SHORT]) == 0
    meta = read_metadata(run_dir / "run.mcap")
    assert meta["link"] == "virtual" and meta["mode"] == "lockstep" and meta["seed"] == "5"
    assert meta["motor"] == "niu2020-ipmsm" and meta["version"] not in ("", "unknown")
    assert json.loads(meta["motor_set"]) == {"rs": 0.9}
    assert json.loads(meta["motor_params"])["rs"] == 0.9
    assert json.loads(meta["controller_params"]) == {"speed_kp": 0.7}
    assert json.loads(meta["target_parameters"])["speed_kp"] == 0.7
    assert json.loads(meta["sensors"])["noise_std_a"] == 0.01
    frames = read_frames(run_dir / "run.mcap")
    ids = [int(i) for i in frames["arbitration_id"]]
    config_param, config_ack, setpoint = 0x210, 0x211, 0x200
    writes = [k for k, i in enumerate(ids) if i == config_param]
    assert len(writes) >= len(json.loads(meta["target_parameters"]))  # every parameter written (resends too)
    assert ids.count(config_ack) >= len(json.loads(meta["target_parameters"]))
    first_setpoint = ids.index(setpoint)
    assert max(writes) < first_setpoint  # configuration, then the enabling Setpoint, then the periods
    assert ids.count(setpoint) >= 2  # enable at the start, disable at the end
    capsys.readouterr()


# messages and help
def test_speed_reference_missed_is_flagged(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "m.json"
    assert main(["run", "--speed", "2900", "--duration", "0.05", "--settle", "0.3", "--no-log",
                 "--json", str(out)]) == 0
    m = json.loads(out.read_text())
    assert m["speed_reference_missed"] is True and m["speed_mean_rpm"] < 2400
    assert "hil: warning: speed reference missed:" in capsys.readouterr().err
    assert main(["run", "--duration", "0.05", "--settle", "0.05", "--no-log", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["speed_reference_missed"] is False
    assert "speed reference missed" not in capsys.readouterr().err


def test_help_lists_controllers_links_and_real_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = capsys.readouterr().out
    text = " ".join(out.split())  # argparse wraps lines (and breaks after hyphens)
    for name in CONTROLLER_NAMES.values():
        assert name in text
    for kind in LINK_KINDS.values():
        assert "".join(kind.summary.split()) in "".join(out.split())
    for default in ("(default niu2020-ipmsm)", "(default mpcc)", "(default steady)", "(default virtual)",
                    "(default lockstep)", "(default 0.0001)", "steady: the motor's rated speed, 1500 for niu2020-ipmsm",
                    "(default 0: ideal)"):
        assert default in text
    assert "(default: None)" not in text


def test_debug_after_the_subcommand(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nope.toml"
    with pytest.raises(Exception, match="config file"):
        main(["run", "--config", str(missing), "--debug"])
    with pytest.raises(Exception, match="config file"):
        main(["--debug", "run", "--config", str(missing)])
    assert main(["run", "--config", str(missing)]) == 2
    _one_line_error(capsys, "config file")


def test_interrupted_run_names_its_partial_log(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    from pmsm_hil.app.cli import run as run_cli

    def interrupted(*args: object, **kwargs: object) -> object:
        (tmp_path / "r" / "run.mcap").write_bytes(b"partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(run_cli, "run_closed_loop", interrupted)
    assert main(["run", "--out", str(tmp_path / "r"), *SHORT]) == 130
    assert f"hil: interrupted; partial log: {tmp_path / 'r' / 'run.mcap'}" in capsys.readouterr().err
