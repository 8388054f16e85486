"""The zhang2021-symmetric compare preset: each controller with and without v3_symmetric."""

from __future__ import annotations

from pmsm_hil.app.compare import load_preset


def test_symmetric_preset_pairs_every_controller() -> None:
    p = load_preset("zhang2021-symmetric")
    specs = {v.label: v for v in p.specs()}
    assert list(specs) == ["mptc1", "mptc1 sym", "mptc2", "mptc2 sym", "mptc3", "mptc3 sym"]
    for c in ("mptc1", "mptc2", "mptc3"):
        assert specs[c].controller == specs[f"{c} sym"].controller == c
        assert specs[c].params == {} and specs[f"{c} sym"].params == {"v3_symmetric": 1.0}
    assert p.params == {"torque_band": 4.0}
    steady = load_preset("zhang2021-steady")
    assert (p.speed_rpm, p.load_nm, p.theta0_rad) == (steady.speed_rpm, steady.load_nm, steady.theta0_rad)
    assert p.paper["mptc2"]["current_thd_pct"] == 6.9
