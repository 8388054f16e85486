"""Real-time set-up helpers of the native loop: the kernel's RT throttling probe and `--cpu` isolation."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from pmsm_hil.hil.runner import loop_config
from pmsm_hil.hil.runner.cpu_isolation import isolate_cpu


@pytest.mark.parametrize(("text", "throttled"), [("950000\n", True), ("-1\n", False), ("0\n", True),
                                                 ("garbage", True)])
def test_rt_throttled_reads_the_kernel_budget(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, text: str,
                                              throttled: bool) -> None:
    f = tmp_path / "sched_rt_runtime_us"
    f.write_text(text)
    monkeypatch.setattr(loop_config, "RT_RUNTIME_FILE", str(f))
    assert loop_config.rt_throttled() is throttled


def test_rt_throttled_when_the_file_is_missing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(loop_config, "RT_RUNTIME_FILE", str(tmp_path / "absent"))
    assert loop_config.rt_throttled() is True


def test_isolate_cpu_moves_every_thread_off_the_cpu_and_restores() -> None:
    before = os.sched_getaffinity(0)
    if len(before) < 2:
        pytest.skip("needs 2 CPUs in this process's mask")  # not in CI_ALLOWED_SKIPS: CI runners have 2+
    cpu = max(before)
    parked = threading.Event()
    seen: dict[str, set[int]] = {}

    def worker() -> None:
        parked.wait(5.0)
        seen["worker"] = os.sched_getaffinity(0)

    t = threading.Thread(target=worker)
    t.start()
    restore = isolate_cpu(cpu)
    try:
        assert os.sched_getaffinity(0) == before - {cpu}
        parked.set()
        t.join(5.0)
        assert seen["worker"] == before - {cpu}  # an existing thread was moved too
    finally:
        restore()
    assert os.sched_getaffinity(0) == before
