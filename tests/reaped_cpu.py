"""CPU seconds of the suite's processes that a helper process reaped rather than the pytest worker (the worker's
RUSAGE_CHILDREN misses them, e.g. the foreign targets tests/runner/foreign_zygote.py forks): tests/conftest.py's
per-test CPU report (HIL_CPU_REPORT) adds them to the test that ended them."""

CPU_S: list[float] = []
