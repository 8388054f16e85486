"""One long-lived target serves run after run: each run numbers its Measurements from 0 again, and a
ConfigParam (every run configures first) restarts the target decoder's sequence tracking."""

from __future__ import annotations

import socket
import subprocess
import sys

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.messages import Measurement


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_decoder_restart_accepts_a_new_sequence() -> None:
    codec = FrameCodec("can")
    dec = codec.decoder()
    meas = [Measurement(seq=s, i_a=1.0, i_b=-0.5, i_c=-0.5, theta_e=0.1, omega_m=10.0, vdc=300.0, status=0)
            for s in (200, 0)]

    def delivered(m: Measurement) -> bool:
        out = [dec.feed(f) for f in codec.encode(m)]
        return any(x is not None for x in out)

    assert delivered(meas[0])
    assert not delivered(meas[1]) and dec.stats.stale >= 1  # seq 0 after 200: stale within one sequence
    dec.restart()
    assert delivered(meas[1])


def test_two_short_runs_against_one_udp_target() -> None:
    host, target = _free_udp_port(), _free_udp_port()
    cmd = [sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--link", f"udp:{target}:{host}",
           "--idle-timeout", "60"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().startswith("ready")
        sc = load_scenario("steady").with_overrides(speed_rpm=1000.0, load_nm=3.0, settle_s=0.0, duration_s=0.02)
        cfg = RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="mpcc",
                        link=f"udp:{host}:{target}", target="external", mode="lockstep", out_dir=None,
                        lockstep_timeout_s=5.0)
        for _ in range(2):
            res = run_closed_loop(cfg)
            assert res.metrics["end_code"] == 0, res.metrics["end_reason"]
            assert res.metrics["total_periods"] == 200 and res.metrics["dut_violations"] == 0
    finally:
        proc.terminate()
        proc.wait(timeout=30)
