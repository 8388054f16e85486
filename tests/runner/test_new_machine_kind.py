"""docs/recipes.md "A new machine kind", proven: a kind the package does not know (an R-L load, tests/runner/rl_kind:
its C kernel, its parameter and plant classes, one registry line) runs closed loop in the C period loop through
its kernel table, with the Python loop's records bit for bit; a kind without a native kernel is refused by the C
loop, never run as a PMSM."""

from __future__ import annotations

import fcntl
import math
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.machine import LAYOUTS, machine_for, unregister_layout
from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.sim_target.fw_build import cache_dir
from tests.runner.loop_pairs import assert_bit_identical, reference_and_c_records

KIND_DIR = Path(__file__).with_name("rl_kind")
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def rl() -> Iterator[ModuleType]:
    """The kind registered, its kernel built into the user's cache (`build_kernel_module` keys the build by the
    hash of the C file, the cdef and the kernel headers: a compile of ~2.5 CPU-s once, not in every session),
    under a lock: a second pytest session may build it at the same moment."""
    sys.path.insert(0, str(KIND_DIR))
    try:
        import rl_load

        build_dir = cache_dir() / "test_kernels"
        build_dir.mkdir(exist_ok=True)
        with (build_dir / "rl_load.lock").open("w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            rl_load.register_rl_load(build_dir)
        yield rl_load
    finally:
        unregister_layout("rl-load")
        sys.path.remove(str(KIND_DIR))
        sys.modules.pop("rl_load", None)


def _cfg(rl: Any, loop: str) -> RunConfig:
    sc = load_scenario("dyno-steady").with_overrides(settle_s=0.02, duration_s=0.03, load_nm=2.0)
    return RunConfig(motor=rl.RlLoadParams.build(r=1.0, l=5e-3, vdc=300.0), scenario=sc, controller="foc", loop=loop)


def test_the_kind_lives_only_in_its_own_files(rl: Any) -> None:
    """Nothing in the package names the kind: its kernel, parameter class and registry line are its own."""
    assert sorted(p.name for p in KIND_DIR.iterdir() if p.suffix in (".c", ".py")) == ["rl_load.c", "rl_load.py"]
    assert (REPO / "src" / "pmsm_hil" / "hil" / "plant.py").is_file()
    for folder in ("src", "firmware_stub"):
        for path in (REPO / folder).rglob("*"):
            if path.suffix in (".py", ".c", ".h", ".toml"):
                text = path.read_text(encoding="utf-8", errors="replace")
                assert "rl_load" not in text and "RlLoad" not in text, path
    assert machine_for(rl.RlLoadParams.build(r=1.0, l=5e-3, vdc=300.0)).layout is LAYOUTS["rl-load"]


def test_a_preset_of_the_kind_loads_through_its_parameter_class(rl: Any, tmp_path: Path) -> None:
    """A motor TOML with `kind = "rl-load"` is read by the kind's parameter class; `--set` overrides apply; an
    unknown kind or key is an error naming it."""
    from pmsm_hil.hil.errors import InputFileError
    from pmsm_hil.hil.presets_loader import load_motor

    path = tmp_path / "rl.toml"
    path.write_text('name = "bench-rl"\nkind = "rl-load"\n[parameters]\nr = 1.0\nl = { value = 5e-3, unit = "H" }\n'
                    'vdc = 300.0\n', encoding="utf-8")
    m = load_motor(str(path), {"r": 2.0})
    assert isinstance(m, rl.RlLoadParams) and (m.r, m.l, m.vdc, m.name) == (2.0, 5e-3, 300.0, "bench-rl")
    assert machine_for(m).layout.kind == "rl-load"
    path.write_text('kind = "rl-lod"\n[parameters]\nr = 1.0\n', encoding="utf-8")
    with pytest.raises(InputFileError, match="kind: no machine kind 'rl-lod'"):
        load_motor(str(path))
    path.write_text('kind = "rl-load"\n[parameters]\nr = 1.0\nl = 1e-3\nvdc = 1.0\nrs = 1.0\n', encoding="utf-8")
    with pytest.raises(InputFileError, match="unknown R-L load parameter"):
        load_motor(str(path))


def test_the_rl_kernel_is_exact_over_one_sub_interval(rl: Any) -> None:
    """From rest, the active vector 100 for Ts: i_α(Ts) = (2/3·Vdc/R)(1 − e^(−R·Ts/L)), i_β = 0 (closed form)."""
    params = rl.RlLoadParams.build(r=1.0, l=5e-3, vdc=300.0)
    plant = rl.RlLoadPlant(params, 1e-4, DynoMechanics(speed_rpm=0.0), trace_dt_s=None)
    plant.advance([4], [100_000])
    smp = plant.sample()
    want = 2.0 / 3.0 * 300.0 / 1.0 * (1.0 - math.exp(-1.0 * 1e-4 / 5e-3))
    assert smp.i_a == pytest.approx(want, rel=1e-14)
    assert smp.i_b == pytest.approx(-0.5 * want, rel=1e-14) and smp.i_c == pytest.approx(-0.5 * want, rel=1e-14)
    assert smp.torque == 0.0


def test_the_c_loop_runs_the_new_kind_as_the_python_loop_does(rl: Any) -> None:
    py, na = reference_and_c_records(_cfg(rl, "auto"))
    assert py.shape[0] == 500
    assert_bit_identical(py, na)
    # the controller regulates the load's currents: FOC's i_q reference is T*/(1.5·p·ψ) = 2/(1.5·2·0.1) A
    window = na[200:]
    i_q_ref = window["torque_ref"].mean() / (1.5 * 2 * 0.1)
    assert abs(window["i_q"].mean() - i_q_ref) < 0.005 * i_q_ref
    assert abs(window["i_d"].mean()) < 0.01 and (na["torque"] == 0.0).all()
    assert np.isnan(na["i_u"]).all() and np.isnan(na["i_x"]).all()  # no second winding set


def test_a_kind_without_a_native_kernel_is_refused(rl: Any) -> None:
    """A kind whose plant class names no kernel table: every run of the product is a ParameterError naming the
    kind (the C loop runs every run and never runs a kind as another machine); only the test suite's reference
    loop can run it."""
    no_kernel = type("NoKernelPlant", (rl.RlLoadPlant,), {"KERNEL_TABLE": None})
    layout = replace(LAYOUTS["rl-load"], kind="rl-load-python-only", plant_class=no_kernel)
    cfg = _cfg(rl, "native")
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(LAYOUTS, "rl-load", layout)
        for loop in ("native", "auto"):
            with pytest.raises(ParameterError, match=f"--loop {loop}: machine kind 'rl-load-python-only' has no"):
                run_closed_loop(replace(cfg, loop=loop))
        res = run_closed_loop(replace(cfg, loop="python"))
    assert res.metrics["loop"] == "python" and res.metrics["end_code"] == 0


def test_the_c_loop_refuses_a_missing_or_mismatched_kernel_table() -> None:
    """The loop's own guard: no table, or a table whose legs the configured Measurement does not carry, ends the
    run at period 0 as a plant error (NL_PLANT_E_KERNEL) before any period runs."""
    from pmsm_hil.hil._loop_native import ffi, lib
    from pmsm_hil.hil._plant_native import ffi as plant_ffi
    from pmsm_hil.hil._plant_native import lib as plant_lib

    six_table = ffi.cast("mk_kernel_t *", int(plant_ffi.cast("uintptr_t", plant_lib.p6_kernel())))
    params, state = ffi.new("char[256]"), ffi.new("char[256]")
    for kernel, meas_format in ((ffi.NULL, lib.NL_MEAS_3), (six_table, lib.NL_MEAS_3)):
        mem = ffi.new("char[]", int(lib.nl_handle_size()))
        h = ffi.cast("nl_handle_t *", mem)
        assert lib.nl_init(h) == 0
        c = lib.nl_config(h)
        c.machine.kernel, c.machine.legs, c.target_link.codec.meas_format = kernel, 3, meas_format
        c.operation.n_total = 10
        c.machine.plant_params, c.machine.plant_state = params, state
        lib.nl_run(h)
        r = lib.nl_result(h)
        assert (r.end, r.plant_rc, r.completed_periods) == (lib.NL_END_PLANT_ERROR, lib.NL_PLANT_E_KERNEL, 0)
        assert lib.nl_wait_full(h, 0, 0) == -1  # the run ended: no slot will fill
        lib.nl_destroy(h)
