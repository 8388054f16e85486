"""The same 16-run plan gives bit-identical metrics on every engine and worker count (wall-clock metrics
aside: src/pmsm_hil/app/sweep/rows.py WALL_CLOCK_METRICS): the local pool with 1 worker (the reference) and 2 workers, a
Dask LocalCluster and a local Ray instance (runs in this process: tests/sweep/test_compare_engines.py).
Dask and Ray are optional extras: their tests skip only when the extra is not installed (CI installs both,
and a skip fails CI)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.app.sweep.rows import WALL_CLOCK_METRICS, is_wall_clock
from tests.sweep._plans import GRID16, deterministic, results


def _sweep(out: Path, *engine: str) -> dict[str, dict[str, Any]]:
    assert main(["sweep", *GRID16, "--out", str(out), "--quiet", *engine]) == 0
    return deterministic(out)


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    """The plan on a local pool of 1 worker."""
    out = tmp_path_factory.mktemp("one-worker")
    rows = _sweep(out, "--workers", "1")
    assert len(rows) == 16 and all(r["end_code"] == 0 for r in rows.values())
    assert {r["controller"] for r in rows.values()} == {"mpcc", "dsvm-20"}
    measured = [c for c in results(out)[next(iter(rows))] if is_wall_clock(c)]
    assert "exec_time_us.median" in measured and "wall_time_s" in measured  # really left out of the comparison
    assert len({r["pid"] for r in results(out).values()}) == 1
    return rows


def _same(reference: dict[str, dict[str, Any]], rows: dict[str, dict[str, Any]]) -> None:
    assert rows.keys() == reference.keys()
    for rid, row in rows.items():
        assert row == reference[rid], rid  # bit-identical: floats compared exactly
        assert row["torque_ripple_rms_nm"] > 0.0


def test_wall_clock_metrics_are_registry_keys() -> None:
    from pmsm_hil.hil.metrics.registry import METRICS

    keys = {m.key for m in METRICS}
    assert set(WALL_CLOCK_METRICS) <= keys


def test_local_pool_two_workers(reference: dict[str, dict[str, Any]], tmp_path: Path) -> None:
    _same(reference, _sweep(tmp_path, "--workers", "2"))
    assert len({r["pid"] for r in results(tmp_path).values()}) == 2


def test_dask_local_cluster(reference: dict[str, dict[str, Any]], tmp_path: Path) -> None:
    pytest.importorskip("dask.distributed", reason="dask not installed (pip install -e '.[dask]')")
    _same(reference, _sweep(tmp_path, "--engine", "dask", "--workers", "2"))


@pytest.fixture(scope="module")
def ray_local() -> Iterator[None]:
    """One local Ray instance for this module (the engine reuses an instance it finds), started as the engine starts
    its own: its workers inherit the BLAS environment, so the tasks run on the workers Ray started with it."""
    ray = pytest.importorskip("ray", reason="ray not installed (pip install -e '.[ray]')")
    from pmsm_hil.app.sweep.engines import init_local_ray

    init_local_ray(ray, 2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def test_ray_local(reference: dict[str, dict[str, Any]], ray_local: None, tmp_path: Path) -> None:
    _same(reference, _sweep(tmp_path, "--engine", "ray"))
    import ray

    assert ray.is_initialized()  # the engine left the instance it did not start running
    from pmsm_hil.app.sweep.engines import blas_env, ray_workers_inherit

    # the rows above came from workers without a per-task environment; any other environment would get one
    assert ray_workers_inherit(ray, blas_env())
    assert not ray_workers_inherit(ray, {**blas_env(), "OPENBLAS_NUM_THREADS": "99"})
