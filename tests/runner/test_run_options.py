"""The run-option schema (src/pmsm_hil/hil/runner/run_options.py) is the one source: every front end offers exactly its
options and refuses a value out of an option's range with an error naming the option (or the key)."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import build_parser, main
from pmsm_hil.app.cli.run import config_schema
from pmsm_hil.app.sweep.configure import base_options
from pmsm_hil.app.sweep.configure import build_config as sweep_config
from pmsm_hil.app.sweep.plan import OUTPUT_KEYS, sweep_keys
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.run_options import BY_FIELD, DEFAULTS, OPTIONS, RUN_OPTIONS, RunOption
from pmsm_hil.testing.runs import HilSettings, build_config, run_choice_option

SHORT = ["--duration", "0.01", "--settle", "0"]


def _subparser(*path: str) -> argparse.ArgumentParser:
    parser = build_parser()
    for name in path:
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = sub.choices[name]
    return parser


def _longs(parser: argparse.ArgumentParser) -> set[str]:
    return {o for a in parser._actions for o in a.option_strings if o.startswith("--")}


def test_every_front_end_offers_the_schemas_options() -> None:
    run_scope = {o.option for o in RUN_OPTIONS if o.scope == "run"}
    everything = {o.option for o in RUN_OPTIONS}
    assert everything <= _longs(_subparser("run"))
    assert run_scope <= _longs(_subparser("sweep"))
    assert set(config_schema()) == set(OPTIONS)  # --config keys
    swept = set(sweep_keys())
    for option in RUN_OPTIONS:
        if option.kind == "table":
            assert f"{option.key}.NAME" in swept
        else:
            assert (option.key in swept) == (option.key not in OUTPUT_KEYS), option.key
    for option in RUN_OPTIONS:  # hil.run(...) keyword arguments (outputs and the link belong to the session)
        if option.key not in ("target", "link", "out", "overwrite", "no_log", "json"):
            assert run_choice_option(option.key) is option


def test_run_config_defaults_are_the_schemas() -> None:
    defaults = {f.name: f.default for f in dataclasses.fields(RunConfig)}
    for name, option in BY_FIELD.items():
        expected = "" if name == "faults" else option.default
        assert defaults[name] == expected, name
    assert DEFAULTS["ts"] == 100e-6 and DEFAULTS["controller"] == "mpcc"


def _out_of_range(option: RunOption) -> str:
    if option.maximum is not None:
        return repr(option.maximum * 2 + 1)
    assert option.minimum is not None
    return repr(option.minimum if option.open_minimum else option.minimum - 1)


BOUNDED = [o for o in RUN_OPTIONS if o.kind in ("number", "integer", "frequency")
           and (o.minimum is not None or o.maximum is not None)]


@pytest.mark.parametrize("option", BOUNDED, ids=[o.key for o in BOUNDED])
def test_out_of_range_is_refused_everywhere_naming_the_option(option: RunOption, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    text = _out_of_range(option)
    if option.kind == "integer":
        text = str(int(float(text)))
    # the command line: one line naming the option
    assert main(["run", "--no-log", *SHORT, f"{option.option}={text}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{option.option} must be" in err[0], err
    # a --config file: names the file and the key
    cfg = tmp_path / "c.toml"
    cfg.write_text(f"{option.key} = {text}\n", encoding="utf-8")
    assert main(["run", "--config", str(cfg), "--no-log", *SHORT]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"config file {cfg}" in err[0] and f"'{option.key}'" in err[0], err
    # hil.run(...) of the pytest plugin and a sweep's base options: the same check
    with pytest.raises(ParameterError, match=f"{option.option} must be"):
        build_config(HilSettings(), None, {"duration": 0.01, option.key: text})
    with pytest.raises(ParameterError, match=f"{option.option} must be"):
        sweep_config(base_options({"duration": 0.01, option.key: text}), ())
    with pytest.raises(ParameterError, match=f"--grid {option.key}: {option.option} must be"):
        sweep_config(base_options({"duration": 0.01}), ((option.key, text),))


def test_help_shows_the_schemas_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for option in RUN_OPTIONS:
        assert option.option in text
    assert "(default lockstep)" in text and "(default 0.5)" in text and "(default Ts/2)" in text


@pytest.mark.parametrize(("motor", "controller", "speed_rpm", "load_nm"),
                         [("niu2020-ipmsm", "mpcc", 1500.0, 7.0), ("im-2k2", "im-foc", 1439.0, 14.6),
                          ("xiao2023-spmsm", "3vmpc", 2000.0, 6.0)])
def test_the_default_scenario_runs_at_the_motors_ratings(motor: str, controller: str, speed_rpm: float,
                                                         load_nm: float) -> None:
    """The default (steady, `at_rated`) scenario's speed and load are the motor's rated speed and torque; the
    options and other scenarios keep theirs."""
    base = {"motor": motor, "controller": controller, "no_log": True}
    sc = RunConfig.from_options(base).scenario
    assert (sc.speed_rpm, sc.load_nm) == (speed_rpm, load_nm)
    sc = RunConfig.from_options({**base, "speed": "900", "load": 2}).scenario
    assert (sc.speed_rpm, sc.load_nm) == (900.0, 2.0)
    sc = RunConfig.from_options({**base, "scenario": "dyno-steady"}).scenario
    assert (sc.speed_rpm, sc.load_nm) == (1000.0, 4.0)
