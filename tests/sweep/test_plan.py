"""Sweep plans: grid options, TOML and CSV plan files, repeats, run ids, and errors that name the key."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.app.sweep.configure import base_options, build_config, build_runs
from pmsm_hil.app.sweep.plan import expand, load_plan, parse_grid, swept_keys
from pmsm_hil.app.sweep.runid import run_id
from pmsm_hil.hil.errors import InputFileError, ParameterError


def test_grid_product_last_key_fastest() -> None:
    grid = parse_grid(["controller=mpcc,dsvm-20", "load=3, 7", "set.rs=4.05,4.5"])
    points = expand((), grid)
    assert len(points) == 8
    assert points[0] == (("controller", "mpcc"), ("load", "3"), ("set.rs", "4.05"))
    assert points[1] == (("controller", "mpcc"), ("load", "3"), ("set.rs", "4.5"))
    assert points[-1] == (("controller", "dsvm-20"), ("load", "7"), ("set.rs", "4.5"))
    assert swept_keys(points) == ["controller", "load", "set.rs"]
    assert parse_grid(["fault=drop=0.1,seed=1;drop=0.2,seed=1"]) == [("fault", ["drop=0.1,seed=1", "drop=0.2,seed=1"])]


@pytest.mark.parametrize(("item", "match"), [
    ("nope=1,2", "--grid: key 'nope' is unknown"),
    ("out=a,b", "key 'out' is an output"),
    ("set=1", "needs a name: set.NAME"),
    ("load", "--grid expects KEY=V1,V2"),
    ("load=3,,7", "--grid load: empty value"),
])
def test_bad_grid_items_name_the_key(item: str, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        parse_grid([item])


@pytest.mark.parametrize(("grid", "message"), [
    ("load=3,x", "--grid load: --load must be a number, got 'x'"),
    ("controller=mpcc,nope", "--grid controller: unknown controller 'nope'"),
    ("ts=1e-4,1", "--grid ts: --ts must be between 5 µs and 1.048575 ms"),
    ("set.rs=4.5,abc", "--grid set.rs: --set rs: value 'abc' is not a number"),
    ("param.nope=1", "--grid param.nope: unknown controller parameter 'nope'"),
    ("mode=lockstep,fast", "--grid mode: --mode must be one of lockstep, realtime, got 'fast'"),
    ("theta0=0,x", "--grid theta0: --theta0 must be a number, got 'x'"),
])
def test_bad_values_get_the_run_options_own_error(grid: str, message: str) -> None:
    """A grid value goes through the run options' own checks (`RunConfig.from_options`): the option's message, the
    key named through the value's source."""
    with pytest.raises(ParameterError) as err:
        build_runs(base_options(), expand((), parse_grid([grid])), 1)
    assert str(err.value).startswith(message)


def test_cli_bad_grid_value_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sweep", "--grid", "load=3,x", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "hil: error: --grid load: --load must be a number, got 'x'"
    assert not (tmp_path / "s").exists()  # nothing ran, nothing written


def test_run_ids_are_stable_and_follow_the_configuration() -> None:
    base = base_options({"duration": "0.1"})
    a = build_config(base, (("controller", "mpcc"), ("load", "3")))
    b = build_config(base, (("load", "3.0"), ("controller", "mpcc")))
    assert run_id(a) == run_id(b)  # same configuration, however written
    assert run_id(replace(a, out_dir=Path("x"), log_trace=True)) == run_id(a)  # logging is not configuration
    assert run_id(build_config(base, (("controller", "mpcc"), ("load", "3.5")))) != run_id(a)
    assert run_id(build_config(base, (("controller", "mpcc"), ("load", "3"), ("set.rs", "4.6")))) != run_id(a)
    assert len(run_id(a)) == 16 and int(run_id(a), 16) >= 0  # 16 hex digits
    # a value given by the base options or by the point is the same run
    assert run_id(build_config(base_options({"duration": "0.1", "load": "3"}), (("controller", "mpcc"),))) == run_id(a)


def test_repeats_turn_the_rotor_and_the_seed() -> None:
    runs = build_runs(base_options({"seed": 5}), [(("controller", "mpcc"),)], 4)
    assert [r.repeat for r in runs] == [0, 1, 2, 3]
    assert [r.cfg.seed for r in runs] == [5, 6, 7, 8]
    assert [r.cfg.sensors.seed for r in runs] == [5, 6, 7, 8]
    assert [r.cfg.scenario.theta0_rad for r in runs] == pytest.approx([k * math.pi / 2 for k in range(4)])
    assert len({r.run_id for r in runs}) == 4
    cols = runs[1].columns()
    assert cols["controller"] == "mpcc" and cols["repeat"] == 1 and cols["seed"] == 6
    assert cols["theta0"] == pytest.approx(math.pi / 2)
    offset = build_runs(base_options(), [(("theta0", "0.5"),)], 2)
    assert [r.cfg.scenario.theta0_rad for r in offset] == pytest.approx([0.5, 0.5 + math.pi])


def test_duplicate_configurations_run_once() -> None:
    runs = build_runs(base_options(), expand((), parse_grid(["load=7,7.0"])), 1)
    assert len(runs) == 1


def test_toml_plan(tmp_path: Path) -> None:
    path = tmp_path / "plan.toml"
    path.write_text('repeat = 2\n[grid]\nload = [3, 7.5]\n"set.rs" = [4.5]\n[grid.param]\nlambda = [0.1, 0.2]\n'
                    '[[runs]]\ncontroller = "mpcc"\n[[runs]]\ncontroller = "foc"\nspeed = 1000\n', encoding="utf-8")
    plan = load_plan(path)
    assert plan.repeat == 2
    assert plan.grid == (("load", ("3", "7.5")), ("set.rs", ("4.5",)), ("param.lambda", ("0.1", "0.2")))
    points = expand(plan.runs, plan.grid)
    assert len(points) == 8
    assert points[-1] == (("controller", "foc"), ("speed", "1000"), ("load", "7.5"), ("set.rs", "4.5"),
                          ("param.lambda", "0.2"))


def test_csv_plan(tmp_path: Path) -> None:
    path = tmp_path / "plan.csv"
    path.write_text("controller,load,set.rs\nmpcc,3,\ndsvm-20,7,4.6\n", encoding="utf-8")
    plan = load_plan(path)
    assert plan.runs == ((("controller", "mpcc"), ("load", "3")),
                         (("controller", "dsvm-20"), ("load", "7"), ("set.rs", "4.6")))


@pytest.mark.parametrize(("name", "text", "match"), [
    ("p.toml", "[grid]\nload = 3\n", "grid.load must be a non-empty list"),
    ("p.toml", "[grid]\nbogus = [1]\n", "plan file .*: grid: key 'bogus' is unknown"),
    ("p.toml", "repeat = 0\n[grid]\nload = [1]\n", "'repeat' must be a whole number"),
    ("p.toml", "[grid]\nload = [true]\n", r"grid.load\[0\] must be a number or a string"),
    ("p.toml", "title = 'x'\n", "unknown key"),
    ("p.csv", "controller,load\nmpcc\n", "row 2: 1 cells, the header has 2"),
    ("p.csv", "controller,wat\nmpcc,1\n", "key 'wat' is unknown"),
])
def test_bad_plan_files_name_the_place(tmp_path: Path, name: str, text: str, match: str) -> None:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputFileError, match=match):
        load_plan(path)


def test_list_prints_the_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sweep", "--grid", "controller=mpcc,dsvm-20", "--repeat", "2", "--list",
                 "--out", str(tmp_path / "s")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1] == "4 runs"
    assert lines[0].endswith("controller=mpcc repeat=0") and len(lines[0].split()[0]) == 16
