"""Configuration as data: `RunConfig.from_options(values, sources)` is the one path from option values to a run's
configuration; layers (defaults < config file < overrides) keep each value's source, and errors name the field and
where its value came from."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import build_parser
from pmsm_hil.app.cli.run import options_from_args
from pmsm_hil.app.sweep.configure import base_options, build_config, build_runs
from pmsm_hil.app.sweep.plan import expand, parse_grid
from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.option_values import DEFAULT, layer
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.run_groups import GROUPS
from pmsm_hil.hil.runner.run_options import RUN_OPTIONS
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.testing.runs import HilSettings, run_values
from pmsm_hil.testing.runs import build_config as plugin_config

QUICK = {"duration": 0.01, "settle": 0.0, "no_log": True}


def test_layers_later_win_and_remember_their_source() -> None:
    values, sources = layer(({"speed": 900.0, "load": 2.0, "set": {"rs": 4.0, "j": 0.01}}, "config file c.toml"),
                            ({"load": "3", "set.rs": "4.5"}, "sweep grid key load"))
    assert values == {"speed": 900.0, "load": "3", "set": {"rs": "4.5", "j": 0.01}}
    assert sources == {"speed": "config file c.toml", "load": "sweep grid key load",
                       "set.rs": "sweep grid key load", "set.j": "config file c.toml"}
    cfg = RunConfig.from_options({**values, **QUICK}, sources)
    assert (cfg.scenario.speed_rpm, cfg.scenario.load_nm) == (900.0, 3.0)
    assert (cfg.motor.rs, cfg.motor.j) == (4.5, 0.01)


def test_precedence_default_config_file_command_line(tmp_path: Path) -> None:
    conf = tmp_path / "c.toml"
    conf.write_text("speed = 800.0\nload = 1.5\nts = 5e-05\n[set]\nrs = 4.2\n", encoding="utf-8")
    args = build_parser().parse_args(["run", "--config", str(conf), "--load", "2.5", "--set", "j=0.02"])
    values, sources = options_from_args(args)
    assert sources["speed"] == f"config file {conf}" and sources["load"] == "--load"
    assert sources["set.rs"] == f"config file {conf}" and sources["set.j"] == "--set"
    cfg = RunConfig.from_options({**values, **QUICK}, sources)
    assert (cfg.scenario.speed_rpm, cfg.scenario.load_nm, cfg.ts_s) == (800.0, 2.5, 5e-5)
    assert (cfg.motor.rs, cfg.motor.j) == (4.2, 0.02)
    assert cfg.controller == "mpcc" and cfg.mode == "lockstep"  # defaults
    assert "controller" not in sources  # a default has no source of its own: "default"


@pytest.mark.parametrize(("source", "expected"), [
    ("--watchdog-periods", "--watchdog-periods must be ≥ 1, got 0"),
    ("config file c.toml", "config file c.toml: 'watchdog_periods' must be ≥ 1, got 0"),
    ("sweep grid key watchdog_periods", "--grid watchdog_periods: --watchdog-periods must be ≥ 1, got 0"),
    ("plan file p.csv key watchdog_periods", "plan file p.csv: watchdog_periods: --watchdog-periods must be ≥ 1"),
    ("hil.run(watchdog_periods=...)", "hil.run(watchdog_periods=...): --watchdog-periods must be ≥ 1, got 0"),
])
def test_an_error_names_the_field_and_its_source(source: str, expected: str) -> None:
    with pytest.raises(ParameterError) as err:
        RunConfig.from_options({**QUICK, "watchdog_periods": 0}, {"watchdog_periods": source})
    assert str(err.value).startswith(expected) and err.value.key == "watchdog_periods"


def test_errors_found_by_the_run_configuration_name_their_source_too() -> None:
    """Cross-field checks inside RunConfig say which field they are about (`ParameterError.key`), never matched
    from the message: the adc delay against Ts, the controller against the motor, a parameter the controller does
    not read, a table item."""
    with pytest.raises(ParameterError, match=r"^config file a.toml: 'adc_delay' must be shorter"):
        RunConfig.from_options({**QUICK, "adc_delay": 2e-4}, {"adc_delay": "config file a.toml"})
    with pytest.raises(ParameterError, match=r"^--grid controller: controller 'mptc2' needs a six-phase motor"):
        RunConfig.from_options({**QUICK, "controller": "mptc2"}, {"controller": "sweep grid key controller"})
    with pytest.raises(ParameterError, match=r"^--grid param.lambda: --param lambda: controller 'foc' does not"):
        RunConfig.from_options({**QUICK, "controller": "foc", "param": {"lambda": 0.5}},
                               {"param.lambda": "sweep grid key param.lambda"})
    with pytest.raises(ParameterError, match=r"^--grid set.rs: --set rs: value 'abc' is not a number"):
        RunConfig.from_options({**QUICK, "set.rs": "abc"}, {"set.rs": "sweep grid key set.rs"})
    with pytest.raises(ParameterError, match=r"^--link: link spec"):
        RunConfig.from_options({**QUICK, "link": "can,bitrate"}, {"link": "--link"})


def test_an_unknown_key_is_named() -> None:
    with pytest.raises(ParameterError, match=r"unknown run option 'speeed' \(known: motor, set, controller"):
        RunConfig.from_options({"speeed": 1.0})
    with pytest.raises(ParameterError, match=r"unknown run option 'ts.x'"):
        RunConfig.from_options({"ts.x": 1.0})


def test_values_may_be_python_values_or_command_line_texts() -> None:
    a = RunConfig.from_options({**QUICK, "ts": 5e-5, "tolerate": 3, "sil_in_process": False, "param": {"speed_kp": 1}})
    b = RunConfig.from_options({**QUICK, "ts": "5e-5", "tolerate": "3", "sil_in_process": "false",
                                "param": ["speed_kp=1"]})
    assert a == b
    with pytest.raises(ParameterError, match=r"--tolerate must be an integer, got 2\.5"):
        RunConfig.from_options({**QUICK, "tolerate": 2.5})
    with pytest.raises(ParameterError, match="--verbose is a flag"):
        RunConfig.from_options({**QUICK, "verbose": "yes"})


def test_grouped_access() -> None:
    cfg = RunConfig.from_options({**QUICK, "ts": 5e-5, "link": "udp,port=1", "target": "spawn", "rt_priority": 0,
                                  "noise": 0.01, "seed": 4})
    assert cfg.machine.params is cfg.motor and cfg.machine.phases == 3
    assert cfg.operation.scenario is cfg.scenario and cfg.operation.load_fmu is None
    assert cfg.target_link.link_spec.kind == "udp" and cfg.target_link.link_spec.options == {"port": 1}
    assert cfg.target_link.target_kind == "spawn" and cfg.target_link.controller == "mpcc"
    assert cfg.timing.ts_s == 5e-5 and cfg.timing.mode == "lockstep" and cfg.timing.loop == "auto"
    assert cfg.sensors.noise_std_a == 0.01 and cfg.sensors.seed == 4
    assert cfg.outputs.out_dir is None and cfg.outputs.log_trace is False
    # every field of RunConfig is in exactly one group
    grouped = [name for names in GROUPS.values() for name in names]
    assert sorted(grouped) == sorted(f.name for f in dataclasses.fields(RunConfig))


def test_the_c_loop_configuration_has_the_run_configuration_groups() -> None:
    """nl_config_t (loop.h) is RunConfig's groups as sub-structs, in the same order, and the NaN constant; the
    real-time set-up reads the timing group alone."""
    from pmsm_hil.hil._loop_native import ffi

    fields = ffi.typeof("nl_config_t").fields
    assert [name for name, _ in fields] == [*GROUPS, "nan"]
    assert all(f.type.kind == "struct" for _, f in fields[:-1])
    timing = {name for name, _ in ffi.typeof("nl_timing_cfg_t").fields}
    assert {"ts_ns", "ts_s", "realtime", "rt_priority", "cpu", "lock_memory"} <= timing


def test_every_option_is_held_by_the_run_configuration_or_cli_only() -> None:
    names = {f.name for f in dataclasses.fields(RunConfig)}
    for option in RUN_OPTIONS:
        held = option.field or (option.part or "").split(".", 1)[0]
        assert (held in names) != option.cli_only, option.key
    assert {o.key for o in RUN_OPTIONS if o.cli_only} == {"json", "overwrite", "expect_hold"}


@pytest.mark.parametrize(("motor", "speed_rpm", "load_nm"),
                         [("niu2020-ipmsm", 1500.0, 7.0), ("im-2k2", 1439.0, 14.6), ("xiao2023-spmsm", 2000.0, 6.0)])
def test_a_hand_built_config_gets_the_presets_ratings(motor: str, speed_rpm: float, load_nm: float) -> None:
    """One place decides the default operating point: a RunConfig built by hand with the default scenario runs at
    the motor's ratings, as `hil run`, a sweep and `hil.run` do; an override keeps its own value."""
    m = load_motor(motor)
    controller = "im-foc" if motor == "im-2k2" else "3vmpc" if motor.startswith("xiao") else "mpcc"
    cfg = RunConfig(motor=m, scenario=load_scenario("steady"), controller=controller)
    assert (cfg.scenario.speed_rpm, cfg.scenario.load_nm) == (speed_rpm, load_nm)
    assert not cfg.scenario.rated
    half = RunConfig(motor=m, scenario=load_scenario("steady").with_overrides(speed_rpm=900.0), controller=controller)
    assert (half.scenario.speed_rpm, half.scenario.load_nm) == (900.0, load_nm)
    opts = RunConfig.from_options({**QUICK, "motor": motor, "controller": controller})
    assert (opts.scenario.speed_rpm, opts.scenario.load_nm) == (speed_rpm, load_nm)
    plugin = plugin_config(HilSettings(motor=motor), None, {"controller": controller, "duration": 0.01})
    assert (plugin.scenario.speed_rpm, plugin.scenario.load_nm) == (speed_rpm, load_nm)


def test_a_sweep_with_a_bad_grid_value_names_the_grid_key() -> None:
    base = base_options({"duration": 0.1})
    with pytest.raises(ParameterError, match=r"^--grid load: --load must be a number, got 'x'$"):
        build_runs(base, expand((), parse_grid(["controller=mpcc", "load=3,x"])), 1)
    with pytest.raises(ParameterError, match=r"^--grid ts: --ts must be between 5 µs"):
        build_config(base, (("ts", "1"),))
    with pytest.raises(ParameterError, match=r"^plan file p.csv: load: --load must be a number"):
        build_config(base, (("load", "x"),), plan=Path("p.csv"))
    # a bad base option (the sweep's command line) is named as its option, not as a grid key
    with pytest.raises(ParameterError, match=r"^--watchdog-periods must be ≥ 1"):
        build_config(base_options({"watchdog_periods": 0}), (("load", "3"),))


def test_the_plugin_builds_from_a_dict() -> None:
    values, sources = run_values(HilSettings(target="spawn", motor="zhang2021-dtpmsm", controller="mptc3"),
                                 Path("/o"), {"speed": 1200, "params": {"lambda": 0.5}, "faults": "drop=0.01"})
    assert values == {"target": "spawn", "link": "udp", "motor": "zhang2021-dtpmsm", "controller": "mptc3",
                      "out": Path("/o"), "speed": 1200, "param": {"lambda": 0.5}, "fault": "drop=0.01"}
    assert sources["target"] == "--hil-target" and sources["speed"] == "hil.run(speed=...)"
    assert sources["param"] == "hil.run(params=...)"
    with pytest.raises(ParameterError, match=r"^hil.run\(speed=...\): --speed must be a number, got 'fast'"):
        plugin_config(HilSettings(), None, {"speed": "fast"})
    with pytest.raises(ParameterError, match=r"^hil.run\(speed=...\): 5000 rpm is at or beyond the motor's overspeed"):
        plugin_config(HilSettings(), None, {"speed": 5000})
    with pytest.raises(ParameterError, match=r"^--grid speed: 5000 rpm is at or beyond"):
        build_config(base_options(), (("speed", "5000"),))
    with pytest.raises(ParameterError, match=r"^scenario 'steady' speed_rpm: 1500 rpm is at or beyond"):
        RunConfig.from_options({"set": {"speed_trip_rpm": 1000.0}, "no_log": True})
    cfg = plugin_config(HilSettings(), None, {"duration": 0.01, "ts": 5e-5})
    assert cfg.timing.ts_s == 5e-5 and cfg.out_dir is None


def test_a_missing_file_is_one_line_naming_it() -> None:
    with pytest.raises(InputFileError, match=r"^--grid motor: .*nope"):
        build_config(base_options(), (("motor", "nope.toml"),))
    assert DEFAULT == "default"


def _exit_code(argv: list[str]) -> int:
    from pmsm_hil.app.cli.main import main

    try:
        return main(argv)
    except SystemExit as exc:  # argparse's own errors
        return int(exc.code or 0)


@pytest.mark.parametrize("argv", [["bench", "loop", "--ts", "1"], ["bench", "realtime", "--ts", "1"],
                                  ["run", "--ts", "1"], ["bench", "loop", "--ts", "1.00000005e-4"]])
def test_the_benches_declare_ts_as_hil_run_does(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    """`--ts` has one declaration and one check (src/pmsm_hil/hil/control_period.py) wherever a period is chosen."""
    assert _exit_code(argv) == 2
    err = capsys.readouterr().err
    assert "--ts must be between 5 µs and 1.048575 ms" in err or "--ts must be a whole number of ns" in err


def test_the_plant_checks_its_period_with_the_same_function() -> None:
    """A run's control period and a plant's period share one check; a plant built outside a run (the tests'
    reference plants ending a period at a trace row's time) steps down to 1 µs, a run's period starts at 5 µs."""
    from pmsm_hil.hil.control_period import MAX_TS_S, MIN_TS_S, PLANT_MIN_TS_S
    from pmsm_hil.hil.machine import machine_for
    from pmsm_hil.hil.mechanics import InertiaMechanics, LoadProfile

    m = load_motor("niu2020-ipmsm")
    mech = InertiaMechanics(LoadProfile.constant(0.0))
    for ts in (MIN_TS_S, MAX_TS_S, 1e-4):
        assert RunConfig(motor=m, scenario=load_scenario("steady"), ts_s=ts).ts_s == ts
        machine_for(m).build_plant(ts, mech, trace_dt_s=None)
    machine_for(m).build_plant(PLANT_MIN_TS_S, mech, trace_dt_s=None)
    for ts in (MIN_TS_S / 2, 2 * MAX_TS_S):
        with pytest.raises(ParameterError, match="--ts must be between 5 µs"):
            RunConfig(motor=m, scenario=load_scenario("steady"), ts_s=ts)
    for ts in (PLANT_MIN_TS_S / 2, 2 * MAX_TS_S):
        with pytest.raises(ParameterError, match="control period 'ts' must be between 1 µs"):
            machine_for(m).build_plant(ts, mech, trace_dt_s=None)
