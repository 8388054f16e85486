"""A user's test file run by tests/load_fmu/test_containment.py in a pytest subprocess: the middle test's load FMU
(LOAD_FMU_BAD) crashes with SIGSEGV in fmi2DoStep at period 100; the session goes on and its JUnit XML lists all
three tests. No project import but pmsm_hil.testing (and os)."""

import os

RUN = {"settle": 0.01, "duration": 0.02, "speed": 1000}


def test_before_the_crash(hil):
    r = hil.run(load_fmu=os.environ["LOAD_FMU_OK"], **RUN)
    assert r.end_code == 0, r.end_reason


def test_the_crash(hil):
    r = hil.run(load_fmu=os.environ["LOAD_FMU_BAD"], load_fmu_set={"fail_at": 0.01}, **RUN)
    assert r.end_code == 3 and "crashed (SIGSEGV in fmi2DoStep at period 100)" in r.end_reason, r.end_reason
    assert len(r.periods) == r.metrics["end_period"] + 1 == 100


def test_after_the_crash(hil):
    r = hil.run(load_fmu=os.environ["LOAD_FMU_OK"], **RUN)
    assert r.end_code == 0, r.end_reason
