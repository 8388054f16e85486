"""`hil replay` is the run's inverse (src/pmsm_hil/hil/runner/replay_run.py, src/pmsm_hil/hil/replay_commands.py):
the Commands of a run's MCAP, or of its CAN log export, drive the plant as the loop did and give back the currents
the run logged, for every bundled controller (switching states, mirrored sequences, duty cycles on CAN FD and classic
CAN, single and double update), every machine kind, inertia and dyno mechanics; a capture with a Command missing is
refused naming its seq, or replayed with `--allow-gaps`."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.machine import THREE_PHASE
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.replay_commands import applied_periods
from pmsm_hil.hil.runlog.can_log import export_frames
from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.replay_run import CURRENTS, replay_run
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.hil.sensors import SensorConfig
from pmsm_hil.protocol.messages import Command

#: the replay reproduces the logged currents to this [A]
TOLERANCE_A = 1e-6
SENSORS = SensorConfig(adc_lsb_a=0.01, noise_std_a=0.05, encoder_counts=4096, seed=3)
#: the machine each controller's paper uses (the C loop's oracle test picks the same)
MOTOR_OF = {"3vmpc": "xiao2023-spmsm", "hv-mpfc": "xiao2023-spmsm", "im-foc": "im-2k2"}


def _controllers() -> list[tuple[str, int]]:
    from pmsm_hil.sim_target.firmware import CONTROLLERS

    return [(c.name, c.phases) for c in CONTROLLERS if c.implemented and c.phases in (3, 6)]


def _case(name: str, phases: int) -> RunConfig:
    """A 20 ms run of controller `name` with its speed step inside (inertia mechanics), CAN FD or classic CAN."""
    link = "virtual" if sum(map(ord, name)) % 2 else "virtual,fd=false"
    if phases == 6:
        sc = load_scenario("steady").with_overrides(speed_rpm=1500.0, load_nm=40.0, settle_s=0.005, duration_s=0.015)
        return RunConfig(motor=load_motor("zhang2021-dtpmsm"), scenario=sc, controller=name, link=link)
    sc = load_scenario("speed-step").with_overrides(settle_s=0.005, duration_s=0.015, speed_step_s=0.01)
    return RunConfig(motor=load_motor(MOTOR_OF.get(name, "niu2020-ipmsm")), scenario=sc, controller=name,
                     sensors=SENSORS, link=link)


def _more_cases() -> dict[str, RunConfig]:
    """Duty cycles on the other link and double update, the flux-map machine, dyno mechanics with a held-speed
    step, a start angle, an ADC delay, a two-mass shaft."""
    foc = _case("foc", 3)
    mpcc = _case("mpcc", 3)
    two_mass = mpcc.scenario.with_overrides(shaft="two-mass", load_inertia_kgm2=4e-4, shaft_stiffness_nm_per_rad=800.0,
                                            shaft_damping_nms_per_rad=0.01)
    dyno = load_scenario("dyno-steady").with_overrides(settle_s=0.005, duration_s=0.015, speed_step_s=0.01,
                                                       initial_speed_rpm=1000.0, speed_rpm=1500.0, theta0_rad=1.1)
    return {"foc-other-link-double-update": replace(foc, link="virtual" if foc.link != "virtual" else
                                                    "virtual,fd=false", pwm_update="double"),
            "fluxmap-mpcc": replace(_case("mpcc", 3), motor=load_motor("niu2020-ipmsm-sat")),
            "dyno-speed-step-fcs-mpc-2": replace(_case("fcs-mpc-2", 3), scenario=dyno, adc_delay_s=20e-6),
            "two-mass-shaft-mpcc": replace(mpcc, scenario=two_mass)}


def _logged_run(cfg: RunConfig, out: Path) -> Path:
    res = run_closed_loop(replace(cfg, out_dir=out))
    # mptc1 trips on the six-phase machine (its x-y current runs away, docs/comparisons/zhang2021.md): the periods
    # up to the trip are replayed all the same
    assert res.metrics["end_code"] == 0 or (cfg.controller == "mptc1" and res.metrics["end_code"] == 3), \
        res.metrics["end_reason"]
    assert res.mcap_path is not None
    return res.mcap_path


def _replayed_currents(csv_path: Path, legs: int) -> np.ndarray:
    rows = np.loadtxt(csv_path, delimiter=",", skiprows=1, ndmin=2)
    return rows[:, 1:1 + legs]  # t, then the phase currents


def _assert_reproduces(mcap: Path, out: Path, capture: Path | None = None) -> int:
    """Replay `mcap` (or `capture` with it) and compare with the logged currents; returns the run's misses."""
    done = replay_run(mcap, out, capture=capture)
    periods = read_periods(mcap)
    legs = len(CURRENTS[6]) if np.isfinite(periods["i_u"]).all() else 3
    logged = np.column_stack([periods[n] for n in CURRENTS[legs]])
    replayed = _replayed_currents(out, legs)
    assert len(replayed) == len(periods) + 2  # the state after each period, the run's last Command applied too
    err = float(np.max(np.abs(replayed[:len(periods)] - logged)))
    assert err <= TOLERANCE_A, err
    assert done.compared == len(periods) and done.max_error_a == pytest.approx(err, abs=1e-15)
    missed = int(periods["missed"].sum())
    assert done.result.gaps == 0 and done.result.commands == len(periods) - missed
    assert missed - 1 <= done.result.run_misses <= missed  # a missed last Command without a frame is never needed
    return missed


@pytest.mark.parametrize(("name", "phases"), _controllers())
def test_replay_of_each_controllers_run_and_of_its_candump_export_gives_the_logged_currents(
        name: str, phases: int, tmp_path: Path) -> None:
    mcap = _logged_run(_case(name, phases), tmp_path / "run")
    _assert_reproduces(mcap, tmp_path / "from_mcap.csv")
    log = tmp_path / "run.log"
    export_frames(mcap, "candump", log)
    _assert_reproduces(mcap, tmp_path / "from_candump.csv", capture=log)


@pytest.mark.parametrize("case", sorted(_more_cases()))
def test_replay_of_duty_cycles_flux_maps_and_dyno_runs_gives_the_logged_currents(case: str, tmp_path: Path) -> None:
    mcap = _logged_run(_more_cases()[case], tmp_path / "run")
    _assert_reproduces(mcap, tmp_path / "from_mcap.csv")
    log = tmp_path / "run.log"
    export_frames(mcap, "candump", log)
    _assert_reproduces(mcap, tmp_path / "from_candump.csv", capture=log)


def test_a_motor_unknown_here_is_rebuilt_from_the_parameters_the_run_logged(tmp_path: Path) -> None:
    """A motor from a TOML file that is gone (here: a name no preset has, a parameter changed): the replay builds it
    from the log's `motor_params`."""
    motor = replace(load_motor("niu2020-ipmsm"), name="bench-motor-gone").with_values(rs=0.4)
    mcap = _logged_run(replace(_case("mpcc", 3), motor=motor), tmp_path / "run")
    _assert_reproduces(mcap, tmp_path / "replay.csv")


@pytest.mark.parametrize(("controller", "policy", "pwm_update"),
                         [("mpcc", "zero", "single"), ("mpcc", "hold", "single"), ("foc", "hold", "double")])
def test_replay_of_a_run_that_lost_commands_applies_its_miss_policy_in_their_place(
        controller: str, policy: str, pwm_update: str, tmp_path: Path) -> None:
    """Command frames dropped on the link (`--fault drop.down`): the run's records mark them `missed` and the replay
    puts the run's miss policy in their place (a held duty-cycle Command compared with each period's carrier half),
    from the MCAP and from its candump export."""
    cfg = replace(_case(controller, 3), faults="drop.down=0.03,seed=5", miss_policy=policy, watchdog_periods=50,
                  tolerate=1000, pwm_update=pwm_update)
    mcap = _logged_run(cfg, tmp_path / "run")
    assert _assert_reproduces(mcap, tmp_path / "from_mcap.csv") > 0
    log = tmp_path / "run.log"
    export_frames(mcap, "candump", log)
    _assert_reproduces(mcap, tmp_path / "from_candump.csv", capture=log)


@pytest.fixture(scope="module")
def foc_classic(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A duty-cycle run on classic CAN (CmdDutyA/B/C) and its candump export."""
    out = tmp_path_factory.mktemp("foc")
    mcap = _logged_run(replace(_case("foc", 3), link="virtual,fd=false"), out / "run")
    log = out / "run.log"
    export_frames(mcap, "candump", log)
    return mcap, log


def _command_ids() -> frozenset[int]:
    from pmsm_hil.protocol import codec, codec_duty

    return frozenset(lay.frame_id for lay in (codec.L_CMD_A, codec.L_CMD_B, codec.L_CMD_C, codec.L_CMD_FD,
                                              codec_duty.L_DUTY_A, codec_duty.L_DUTY_B, codec_duty.L_DUTY_C,
                                              codec_duty.L_DUTY_FD))


def _without_command(log: Path, seq: int, out: Path) -> Path:
    """The candump log `log` without the frames of Command `seq` (one CAN FD frame or its classic parts)."""
    from pmsm_hil.protocol.codec import FrameDecoder
    from pmsm_hil.protocol.frame import Frame

    ids = _command_ids()
    lines = log.read_text().splitlines()
    decoder = FrameDecoder(ordered=False)
    parts: list[int] = []
    drop: list[int] = []
    for i, line in enumerate(lines):
        ident, _, data = line.split()[2].partition("#")
        fd = data.startswith("#")
        msg = decoder.feed(Frame(int(ident, 16), bytes.fromhex(data[2:] if fd else data), fd))
        if int(ident, 16) in ids:
            parts.append(i)
        if isinstance(msg, Command):
            if msg.seq == seq:
                drop = list(parts)
            parts = []
    assert drop, f"no Command seq {seq} in {log}"
    out.write_text("\n".join(line for i, line in enumerate(lines) if i not in drop) + "\n")
    return out


@pytest.mark.parametrize("seq", [0, 37])
def test_a_capture_with_a_command_removed_is_refused_naming_its_seq(
        foc_classic: tuple[Path, Path], seq: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mcap, log = foc_classic
    cut = _without_command(log, seq, tmp_path / "cut.log")
    out = tmp_path / "o.csv"
    assert main(["replay", str(cut), "--run-log", str(mcap), "--output", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"Command seq {seq} missing" in err and "--allow-gaps" in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()
    assert main(["replay", str(cut), "--run-log", str(mcap), "--output", str(out), "--allow-gaps"]) == 0
    assert "1 missing Command(s) held as the zero vector" in capsys.readouterr().out
    periods = read_periods(mcap)
    replayed = _replayed_currents(out, 3)
    logged = np.column_stack([periods[n] for n in CURRENTS[3]])
    same = np.max(np.abs(replayed[:len(periods)] - logged), axis=1) <= TOLERANCE_A
    assert same[:seq + 2].all() and not same.all()  # the same up to the held period, not after it


@pytest.mark.parametrize(("fmt", "suffix"), [("asc", ".asc"), ("blf", ".blf"), ("csv", ".csv")])
def test_replay_of_the_other_export_formats_gives_the_logged_currents(foc_classic: tuple[Path, Path], fmt: str,
                                                                      suffix: str, tmp_path: Path) -> None:
    mcap, _ = foc_classic
    log = tmp_path / f"run{suffix}"
    export_frames(mcap, fmt, log)
    _assert_reproduces(mcap, tmp_path / "replay.csv", capture=log)


def test_cli_replays_a_run_log_and_says_how_close_it_came(foc_classic: tuple[Path, Path], tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    mcap, _ = foc_classic
    assert main(["replay", str(mcap), "--output", str(tmp_path / "o.csv")]) == 0
    out = capsys.readouterr().out
    n = len(read_periods(mcap))
    assert f"replayed {n} Commands of {mcap} through the plant over {n + 1} periods" in out
    assert f"largest |replayed - logged| phase current over the run's {n} periods: " in out
    assert main(["replay", str(mcap), "--output", str(tmp_path / "p.csv"), "--rerun-save",
                 str(tmp_path / "x.rrd")]) == 2
    assert "choose one" in capsys.readouterr().err
    assert main(["replay", str(mcap), "--output", str(tmp_path / "q.csv"), "--rpm", "1000"]) == 2
    assert "--rpm: the run's set-up comes from its log" in capsys.readouterr().err
    assert not (tmp_path / "p.csv").exists() and not (tmp_path / "q.csv").exists()


def test_command_k_drives_period_k_plus_1_and_misses_follow_the_runs_policy() -> None:
    ts = 100_000

    def cmd(seq: int, state: int) -> Command:
        return Command(seq, (state,), (ts,))

    applied = applied_periods([cmd(0, 1), cmd(1, 2), cmd(2, 3)], ts_ns=ts, layout=THREE_PHASE)
    assert [s for s, _ in applied.sequences] == [(0,), (1,), (2,), (3,)]
    held = applied_periods([cmd(0, 1), cmd(2, 3)], ts_ns=ts, layout=THREE_PHASE, run_misses=[1], miss_policy="hold")
    assert [s for s, _ in held.sequences] == [(0,), (1,), (1,), (3,)] and held.run_misses == 1 and held.gaps == 0
    gaps = applied_periods([cmd(0, 1), cmd(2, 3)], ts_ns=ts, layout=THREE_PHASE, allow_gaps=True)
    assert [s for s, _ in gaps.sequences] == [(0,), (1,), (0,), (3,)] and gaps.gaps == 1
    wrapped = applied_periods([cmd(65534, 1), cmd(65535, 2), cmd(0, 3), cmd(1, 4)], ts_ns=ts, layout=THREE_PHASE,
                              first_seq=None)  # a capture started during a run, across the seq wrap
    assert [s for s, _ in wrapped.sequences] == [(0,), (1,), (2,), (3,), (4,)] and wrapped.commands == 4
    duty = applied_periods([Command(0, (), (), duties=(0.5, 0.5, 0.5))], ts_ns=ts, layout=THREE_PHASE)
    assert duty.sequences[1] == ((0, 7, 0), (25_000, 50_000, 25_000))  # the carrier, not "durations sum to 0 ns"
