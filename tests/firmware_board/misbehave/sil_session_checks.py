"""A user's test file run under `--hil-target sil:<misbehave/crash library> --hil-controller external` by
tests/firmware_board/test_sil_isolation.py: the firmware crashes (SIGSEGV) at step 500, in the middle test's
run; the session goes on and its JUnit XML lists all three tests. No project import but pmsm_hil.testing."""


def test_before_the_crash(hil):
    r = hil.run(settle=0.01, duration=0.02, expect_hold=False)  # 300 periods: the crash at step 500 is not reached
    assert r.end_code == 0, r.end_reason


def test_the_crash(hil):
    r = hil.run(settle=0.02, duration=0.1)
    assert r.end_code == 3 and "target crashed (SIGSEGV at period 500)" in r.end_reason, r.end_reason
    assert len(r.periods) == r.metrics["end_period"] + 1 == 501


def test_after_the_crash(hil):
    r = hil.run(settle=0.01, duration=0.02, expect_hold=False)  # a fresh target process: a fresh firmware
    assert r.end_code == 0, r.end_reason
