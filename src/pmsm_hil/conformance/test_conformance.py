"""The conformance tests: `pytest --pyargs pmsm_hil.conformance --hil-target KIND` (see the package docstring).
Each test checks one rule of `pmsm_hil.conformance.RULES` and fails with `conformance rule 'NAME' broken`."""

from __future__ import annotations

from typing import TYPE_CHECKING

import pytest

from pmsm_hil.conformance import RULES, broken
from pmsm_hil.hil.runner.contract import RULES as CONTRACT_RULES

if TYPE_CHECKING:
    from pmsm_hil.conformance.probe import ProbeReport
    from pmsm_hil.testing.plugin import HilSession
    from pmsm_hil.testing.runs import HilResult

#: the speed-mode run: 1000 → 1100 rpm at 10 ms under 2 N·m, 60 ms in all
SPEED_SCENARIO = """name = "conformance-speed"
mechanics = "inertia"
initial_speed_rpm = 1000.0
speed_rpm = 1100.0
speed_step_s = 0.01
load_nm = 2.0
settle_s = 0.01
duration_s = 0.05
"""
#: the speed must be within this fraction of the reference over the last SPEED_TAIL_S of the run
SPEED_TOLERANCE, SPEED_TAIL_S = 0.01, 0.02


@pytest.fixture(scope="module")
def contract_run(hil_session: HilSession) -> HilResult | str:
    """One closed-loop run in speed mode with a speed step, every contract finding tolerated and counted; the
    error when it could not start (a parameter the target rejected, a link that does not open)."""
    from pmsm_hil.hil.errors import HilError
    from pmsm_hil.protocol.errors import ProtocolError

    scenario = hil_session.folder("conformance-scenario") / "speed.toml"
    scenario.write_text(SPEED_SCENARIO, encoding="utf-8")
    try:
        return hil_session.run("conformance-run", scenario=scenario, tolerate=1_000_000_000)
    except (HilError, ProtocolError) as exc:
        return f"{type(exc).__name__}: {exc}"


@pytest.fixture(scope="module")
def probe_report(hil_session: HilSession) -> ProbeReport:
    """The probe's findings (dyno plant at 500 rpm)."""
    from pmsm_hil.conformance.probe import PROBE_LOCKSTEP_TIMEOUT_S, probe_target
    from pmsm_hil.testing.runs import build_config

    cfg = build_config(hil_session.settings, None, {"scenario": "dyno-steady", "speed": 500, "load": 0, "settle": 0,
                                                    "lockstep_timeout": PROBE_LOCKSTEP_TIMEOUT_S})
    return probe_target(cfg)


def _ran_periods(run: HilResult | str, rule: str) -> HilResult:
    """The run, if it ran periods; else `rule` fails as not checked, naming why."""
    if isinstance(run, str):
        pytest.fail(broken(rule, f"not checked: the run could not start: {run}"), pytrace=False)
    if run.metrics["end_period"] < 0:
        pytest.fail(broken(rule, f"not checked: the run ended before its first period: {run.end_reason}"),
                    pytrace=False)
    return run


@pytest.mark.parametrize("rule", CONTRACT_RULES)
def test_contract_rule(rule: str, contract_run: HilResult | str) -> None:
    """missing, sequence, state_code, durations, frame: no finding of the rule in the whole run."""
    run = _ran_periods(contract_run, rule)
    count = run.metrics["dut_violations_by_rule"].get(rule, 0)
    if count:
        first = next((v for v in run.metrics["dut_violation_list"] if v["rule"] == rule), None)
        example = (f"; first at period {first['period']} (seq {first['seq']}): {first['detail']} [{first['frame']}]"
                   if first is not None else "")
        pytest.fail(broken(rule, f"{count} finding(s) in {run.metrics['total_periods']} periods{example}"),
                    pytrace=False)


def test_config_ack(contract_run: HilResult | str, probe_report: ProbeReport) -> None:
    if isinstance(contract_run, str):
        pytest.fail(broken("config_ack", f"the run could not start: {contract_run}"), pytrace=False)
    if contract_run.metrics["end_period"] < 0 and "configuring" in contract_run.end_reason:
        pytest.fail(broken("config_ack", contract_run.end_reason), pytrace=False)
    _probe_rule(probe_report, "config_ack")


def test_speed_mode(contract_run: HilResult | str) -> None:
    run = _ran_periods(contract_run, "speed_mode")
    speed = run.signal("speed_rpm")
    ref = run.signal("speed_ref_rpm").y[-1]
    t_end = float(speed.t[-1])
    mean = speed.mean(t_end - SPEED_TAIL_S, t_end)
    ran_through = run.end_code == 0 or run.end_reason.startswith("safe stop not confirmed")  # that is safe_stop's
    if not ran_through or abs(mean - ref) > SPEED_TOLERANCE * ref:
        pytest.fail(broken("speed_mode", f"reference {ref:.0f} rpm (step from 1000 rpm at 10 ms, 2 N·m load): mean "
                                         f"speed over the last {SPEED_TAIL_S * 1e3:g} ms {mean:.1f} rpm, allowed "
                                         f"± {SPEED_TOLERANCE:.0%}; run ended: {run.end_reason}"),
                    pytrace=False)


@pytest.mark.parametrize("rule", ["setpoint_disabled", "torque_mode", "safe_state", "watchdog", "fault_mode",
                                  "fault_controller"])
def test_probe_rule(rule: str, probe_report: ProbeReport) -> None:
    _probe_rule(probe_report, rule)


def test_safe_stop(contract_run: HilResult | str, probe_report: ProbeReport) -> None:
    """The disabling Setpoint of the probe (while running) and the one ending the run are both confirmed."""
    if isinstance(contract_run, str):
        pytest.fail(broken("safe_stop", f"not checked: the run could not start: {contract_run}"), pytrace=False)
    if contract_run.metrics.get("safe_stop_confirmed") is not True:
        pytest.fail(broken("safe_stop", f"at the end of the run: {contract_run.metrics.get('safe_stop_observed')}"),
                    pytrace=False)
    _probe_rule(probe_report, "safe_stop")


def _probe_rule(report: ProbeReport, rule: str) -> None:
    if report.findings.get(rule):
        pytest.fail(broken(rule, "; ".join(report.findings[rule])), pytrace=False)
    if rule not in report.reached:
        pytest.fail(broken(rule, f"not checked: the probe stopped earlier: {report.stopped}"), pytrace=False)


def test_every_rule_has_a_test() -> None:
    """The rule table and the tests above stay in step."""
    tested = {*CONTRACT_RULES, "config_ack", "speed_mode", "setpoint_disabled", "torque_mode", "safe_state",
              "safe_stop", "watchdog", "fault_mode", "fault_controller"}
    assert tested == set(RULES), sorted(set(RULES) ^ tested)
