"""The C++ template firmware (examples/my_firmware_cpp: classes, global objects built by static constructors, its
own parameter `bandwidth`) builds for both boards, holds the rated point as controller `external` (the default
for a user firmware), and its SIL and QEMU runs are bit-identical: -ffp-contract=off keeps the M4F from fusing
multiply-adds."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.messages import ConfigAck, ConfigParam
from pmsm_hil.sim_target.sil import SilFirmware
from tests.firmware_board._runs import MACHINERY_COLUMNS, MACHINERY_KEYS, assert_holds_rated, metrics, rated
from tests.firmware_board.conftest import ROOT, built

CPP = ROOT / "examples" / "my_firmware_cpp"
@pytest.fixture(scope="module")
def cpp_sil() -> Path:
    return built("host", CPP)  # C flags stay off C++ sources (-std=c99 on a C++ file is a warning)


@pytest.fixture(scope="module")
def cpp_elf() -> Path:
    return built("mps2-an386", CPP)


def test_cpp_template_sil_and_qemu_are_bit_identical(cpp_sil: Path, cpp_elf: Path, tmp_path: Path) -> None:
    runs = {}
    for kind, path in (("sil", cpp_sil), ("qemu", cpp_elf)):
        out = tmp_path / kind
        runs[kind] = (metrics(rated(f"{kind}:{path}", controller="external", settle_s=0.03, duration_s=0.07,
                                    out_dir=out)), read_periods(out / "run.mcap"))
    (m_sil, rec_sil), (m_qemu, rec_qemu) = runs["sil"], runs["qemu"]
    assert_holds_rated(m_sil)
    assert_holds_rated(m_qemu)
    assert m_qemu["exec_instructions"]["median"] > 100
    # not the firmware's doing: link counters are the links' (socketpair vs emulated UART); the torque error is
    # the host's (against T_load + B·ω_ref + J·dω_ref/dt), the same for both
    per_target = {"link_auth_dropped"}
    shared = sorted(set(m_sil) & set(m_qemu) - MACHINERY_KEYS - per_target)
    assert len(shared) > 30
    assert {k: m_sil[k] for k in shared} == {k: m_qemu[k] for k in shared}
    assert len(rec_sil) == len(rec_qemu) > 900
    for name in rec_sil.dtype.names:
        if name not in MACHINERY_COLUMNS and name != "torque_ref":  # torque_ref: SIL's debug output only
            assert np.array_equal(rec_sil[name], rec_qemu[name], equal_nan=True), name


def test_firmware_parameter_is_applied_and_checked(cpp_sil: Path) -> None:
    slow = metrics(rated(f"sil:{cpp_sil}", controller="external", controller_params={"bandwidth": 300.0}))
    fast = metrics(rated(f"sil:{cpp_sil}", controller="external", controller_params={"bandwidth": 3000.0}))
    assert_holds_rated(fast)
    assert slow["torque_ripple_rms_nm"] != fast["torque_ripple_rms_nm"]  # the firmware got the values
    with pytest.raises(ParameterError, match=r"--param bandwidth=50: outside the firmware's range \[100, 20000\]"):
        rated(f"sil:{cpp_sil}", controller="external", controller_params={"bandwidth": 50.0})
    with pytest.raises(ParameterError, match=r"unknown controller parameter 'bandwith'.*declares: bandwidth"):
        rated(f"sil:{cpp_sil}", controller="external", controller_params={"bandwith": 500.0})


def test_core_rejects_a_declared_parameter_out_of_range(cpp_sil: Path) -> None:
    fw = SilFirmware(cpp_sil)
    codec = FrameCodec("canfd")
    dec = codec.decoder(ordered=False)

    def ack(value: float) -> object:
        [frame] = codec.encode(ConfigParam(param_id=128, value=value))  # type: ignore[arg-type]
        [reply] = fw.feed(frame)
        return dec.feed(reply)

    f32 = struct.unpack("<f", struct.pack("<f", 2000.0))[0]
    assert ack(2000.0) == ConfigAck(param_id=128, value=f32, status=0)
    assert ack(50.0).status == 5  # type: ignore[attr-defined]
    [nan_ack] = fw.feed(Frame(0x210, bytes([128]) + struct.pack("<I", 0x7FC00000), False))  # a NaN on the wire
    assert dec.feed(nan_ack).status == 5  # type: ignore[union-attr]


def test_sweeps_and_the_pytest_plugin_take_firmware_parameters(cpp_sil: Path) -> None:
    from pmsm_hil.app.sweep.configure import base_options, build_config
    from pmsm_hil.testing.runs import HilSettings
    from pmsm_hil.testing.runs import build_config as plugin_config

    sweep = build_config(base_options({"target": f"sil:{cpp_sil}"}), (("param.bandwidth", "2500"),))
    plugin = plugin_config(HilSettings(target=f"sil:{cpp_sil}"), None, {"params": {"bandwidth": 2500.0}})
    for cfg in (sweep, plugin):
        assert cfg.controller == "external"  # a user firmware's default
        sent = {int(k): (getattr(k, "name", ""), v) for k, v in cfg.target_parameters().items()}
        assert sent[128] == ("bandwidth", 2500.0)
    with pytest.raises(ParameterError, match=r"param\.bandwidth: .*outside the firmware's range"):
        build_config(base_options({"target": f"sil:{cpp_sil}"}), (("param.bandwidth", "1e6"),))


def test_a_controller_the_firmware_lacks_names_the_option(cpp_sil: Path) -> None:
    res = run_closed_loop(rated(f"sil:{cpp_sil}", controller="foc", settle_s=0.01, duration_s=0.01))
    assert res.metrics["end_code"] == 3
    assert "does not implement controller 'foc' (a firmware of your own runs as --controller external)" in \
        res.metrics["end_reason"]


def test_default_controller_of_a_target(cpp_sil: Path, reference_sil: Path) -> None:
    from pmsm_hil.sim_target.fw_build import REFERENCE_SRC
    from pmsm_hil.sim_target.fw_params import default_controller

    assert default_controller(f"sil:{cpp_sil}", "mpcc") == "external"
    assert default_controller(f"sil:{CPP}", "mpcc") == "external"  # a source folder, built by the run
    assert default_controller(f"sil:{reference_sil}", "mpcc") == "mpcc"
    assert default_controller(f"sil:{REFERENCE_SRC}", "mpcc") == "mpcc"
    assert default_controller("sil:/no/such.so", "mpcc") == "mpcc"  # the target's own check names it
    assert default_controller("auto", "mpcc") == "mpcc"
