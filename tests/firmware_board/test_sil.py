"""SIL: the reference firmware built as a host library behind the C target core runs like the in-process
Python target (bit-identical metrics: same C control law, same decoded float32 inputs)."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.messages import ConfigAck, ConfigParam, Fault, Heartbeat, Measurement, Setpoint
from pmsm_hil.sim_target.firmware import FirmwareError
from pmsm_hil.sim_target.sil import SilFirmware
from tests.firmware_board._runs import assert_like, metrics, rated

KEYS = ("speed_mean_rpm", "torque_mean_nm", "torque_ripple_rms_nm", "current_thd_pct", "switching_freq_khz")


def test_reference_sil_equals_inproc(reference_sil: Path, tmp_path: Path) -> None:
    ref = metrics(rated())
    sil = metrics(rated(f"sil:{reference_sil}", out_dir=tmp_path / "sil"))
    assert_like(sil, ref)
    for key in KEYS:
        assert sil[key] == ref[key], key
    assert sil["dut_violations"] == 0
    assert sil["loop"] == "native"  # the C loop, the library served by its pump in the callback link
    assert sil["safe_stop_confirmed"] is True and sil["safe_stop_observed"] == "HeartbeatTarget state idle"
    assert (tmp_path / "sil" / "run.mcap").stat().st_size > 0  # logging works as with any target


def test_sil_from_source_folder(reference_sil: Path) -> None:
    src = Path(__file__).resolve().parents[2] / "firmware_stub" / "target" / "reference"
    m = metrics(rated(f"sil:{src}", settle_s=0.02, duration_s=0.05))
    assert m["speed_mean_rpm"] == pytest.approx(1500.0, rel=0.01)


def test_core_protocol_behaviour(reference_sil: Path) -> None:
    """ConfigAck echoes bit for bit; unknown controller -> FaultTarget not_implemented; bad mode -> invalid_config;
    heartbeat answered; disabled -> zero vector over Ts; a disabling Setpoint -> HeartbeatTarget idle."""
    fw = SilFirmware(reference_sil)
    codec = FrameCodec("canfd")
    dec = codec.decoder(ordered=False)

    def send(msg: object) -> list[object]:
        out = []
        for frame in codec.encode(msg):  # type: ignore[arg-type]
            for reply in fw.feed(frame):
                got = dec.feed(reply)
                if got is not None:
                    out.append(got)
        return out

    f32 = struct.unpack("<f", struct.pack("<f", 5e-5))[0]
    assert send(ConfigParam(param_id=6, value=5e-5)) == [ConfigAck(param_id=6, value=f32, status=0)]
    assert send(ConfigParam(param_id=1, value=-1.0))[0].status == 5  # type: ignore[attr-defined]
    for pid, bits in ((2, 0x7FC12345), (6, 0xFF800000), (6, 0x3B03126F)):  # NaN, -inf, ts 2 ms: no Command carries it
        raw = struct.pack("<I", bits)
        [ack] = [r for r in fw.feed(Frame(0x210, bytes([pid]) + raw, False))]
        assert ack.data[1:5] == raw and ack.data[5] == 5  # refused, the value echoed bit for bit
    fault = send(Setpoint(enable=True, mode=0, reference=1.0, controller_id=255))
    assert isinstance(fault[0], Fault) and fault[0].code == 6 and fault[0].detail == 255
    fault = send(Setpoint(enable=True, mode=7, reference=1.0, controller_id=1))
    assert isinstance(fault[0], Fault) and fault[0].code == 5 and fault[0].detail == 7
    hb = send(Heartbeat(node=0, state=1, counter=42))
    assert hb == [Heartbeat(node=1, state=1, counter=42)]
    cmd = send(Measurement(seq=9, i_a=0.0, i_b=0.0, i_c=0.0, theta_e=0.0, omega_m=0.0, vdc=300.0, status=0))[0]
    assert cmd.seq == 9 and cmd.states == (0,) and cmd.durations_ns == (50_000,)  # type: ignore[attr-defined]
    # the confirmed safe stop: every disabling Setpoint answered with HeartbeatTarget idle, its own counter (a
    # Fault first when the Setpoint also names a controller it lacks)
    assert send(Setpoint(enable=False, mode=0, reference=0.0, controller_id=1)) == [Heartbeat(node=1, state=1,
                                                                                                   counter=0)]
    got = send(Setpoint(enable=False, mode=0, reference=0.0, controller_id=255))
    assert isinstance(got[0], Fault) and got[0].code == 6 and got[1:] == [Heartbeat(node=1, state=1, counter=1)]


def test_sil_errors(tmp_path: Path) -> None:
    with pytest.raises(FirmwareError, match="not found"):
        SilFirmware(tmp_path / "missing.so")
    with pytest.raises((HilError, FirmwareError)):
        run_closed_loop(rated(f"sil:{tmp_path}", duration_s=0.01))  # a folder without CMakeLists.txt


def test_sil_other_scenario_equals_inproc(reference_sil: Path) -> None:
    """Any scenario: a speed step (speed reference changes mid-run, Setpoint re-sent) runs identically."""
    from dataclasses import replace

    from pmsm_hil.hil.runner.scenario import load_scenario

    sc = load_scenario("speed-step")
    sc = sc.with_overrides(duration_s=min(sc.duration_s, 0.1), settle_s=min(sc.settle_s, 0.02))
    base = replace(rated(), scenario=sc)
    ref = metrics(base)
    sil = metrics(replace(base, target=f"sil:{reference_sil}"))
    for key in ("speed_mean_rpm", "torque_mean_nm", "torque_ripple_rms_nm"):
        assert sil[key] == ref[key], key


@pytest.mark.parametrize("link", ["default", "udp"])
def test_an_isolated_sil_run_logs_the_torque_reference_as_the_in_process_one(reference_sil: Path,
                                                                             link: str) -> None:
    """The SIL target in its own process copies each step's torque reference (hil_app_cmd_t's debug output, no
    frame carries it) to memory the host maps: the logged torque_ref is the in-process SIL run's, period by
    period, not NaN (over the default socket pair and over UDP)."""
    from dataclasses import replace

    import numpy as np

    from pmsm_hil.hil.runner.run import run_closed_loop

    base = rated(f"sil:{reference_sil}", settle_s=0.01, duration_s=0.03)
    isolated_cfg = base if link == "default" else replace(base, link="udp")
    isolated = run_closed_loop(isolated_cfg)
    inproc = run_closed_loop(replace(base, sil_in_process=True))
    assert isolated.metrics["end_code"] == inproc.metrics["end_code"] == 0
    assert isolated.metrics["loop"] == "native"
    got, want = (r.outcome.periods.all()["torque_ref"] for r in (isolated, inproc))
    assert got.shape == want.shape and np.all(np.isfinite(got[1:]))
    np.testing.assert_array_equal(got, want)
    assert isolated.metrics["torque_error_reference"] == inproc.metrics["torque_error_reference"]
    # one torque error for every target: from the host's records, the same records give the same number
    assert isolated.metrics["torque_error_mean_nm"] == inproc.metrics["torque_error_mean_nm"]
