"""`hil bench loop --cross-process pycan,socketcan`: a python-can adapter to the native target, the
Python reference loop against the C loop in the same run — through the callback link (pycan: an adapter whose I/O
is a Python library) and through the native SocketCAN wire (python-can's socketcan interface; needs vcan0, which
`.ci/vcan-vm` provides)."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.app.cli import bench_loop

_progress: list[str] = []


def test_pycan_pair_measures_both_loops_against_the_native_target() -> None:
    out = bench_loop._adapter_pair(bench_loop._base(0.01), "pycan", 1, "1 run", _progress.append)
    assert out["lockstep_pycan_python_hz"] > 0 and out["lockstep_pycan_native_hz"] > 0, out
    assert out["pycan_native_speedup"] == out["lockstep_pycan_native_hz"] / out["lockstep_pycan_python_hz"]
    assert any("python-can adapter (hiludp)" in line for line in _progress)


@pytest.mark.skipif(not Path("/sys/class/net/vcan0").exists(),
                    reason="no SocketCAN interface vcan0 (.ci/vcan-vm runs this)")
def test_socketcan_pair_measures_both_loops_on_vcan() -> None:
    out = bench_loop._adapter_pair(bench_loop._base(0.01), "socketcan", 1, "1 run", _progress.append)
    assert out["lockstep_socketcan_python_hz"] > 0 and out["lockstep_socketcan_native_hz"] > 0, out


@pytest.mark.skipif(Path("/sys/class/net/vcan0").exists(), reason="this machine has vcan0")
def test_the_adapter_pair_without_its_interface_is_an_error_entry_naming_it() -> None:
    out = bench_loop._adapter_pair(bench_loop._base(0.01), "socketcan", 1, "1 run", _progress.append)
    assert list(out) == ["lockstep_socketcan_error"]
    assert out["lockstep_socketcan_error"].startswith(f"the native target did not start on "
                                                      f"{bench_loop.SOCKETCAN_BENCH_SPEC}")
