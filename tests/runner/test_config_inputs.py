"""Bad ConfigParam values (NaN, ±inf, out of range, a Ts no Command can carry) are answered with ConfigAck
status 5 invalid_config by both targets, the Python one (sim_target) and the C target core, which keep serving;
a `--ts` the frame format cannot carry is refused up front."""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterator
from dataclasses import replace

import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.core_link import NativeCoreLink
from pmsm_hil.hil.runner.run_config import RunConfig, check_params_used
from pmsm_hil.hil.runner.run_options import MAX_TS_S
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.protocol.codec import MAX_DURATION_NS, FrameCodec
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.ids import ParamId, Status
from pmsm_hil.protocol.layout import load_layouts
from pmsm_hil.protocol.messages import Command, ConfigAck, Measurement
from pmsm_hil.sim_target.target import SimTarget

CONFIG_PARAM_ID = load_layouts()["ConfigParam"].frame_id
#: float32 bit patterns a ConfigParam frame can carry that no parameter accepts: quiet NaNs (with a payload,
#: negative), ±inf
BAD_BITS = (0x7FC00000, 0x7FC12345, 0xFFC00001, 0x7F800000, 0xFF800000)


class _MemLink:
    """In-memory link to a SimTarget: frames pushed in, replies collected."""

    fd = True

    def __init__(self) -> None:
        self.inbox: list[Frame] = []
        self.out: list[Frame] = []

    def send(self, frames: list[Frame]) -> None:
        self.out.extend(frames)

    def poll(self) -> Frame | None:
        return self.inbox.pop(0) if self.inbox else None

    def recv(self, timeout_s: float) -> Frame | None:
        return self.poll()

    def close(self) -> None:
        pass


Exchange = Callable[[Frame], list[Frame]]


def _python_target() -> Iterator[Exchange]:
    link = _MemLink()
    target = SimTarget(link, FrameCodec("canfd"))  # type: ignore[arg-type]

    def exchange(frame: Frame) -> list[Frame]:
        link.inbox.append(frame)
        target.service()
        out, link.out = link.out, []
        return out

    yield exchange


def _c_core() -> Iterator[Exchange]:
    link = NativeCoreLink(fd=True)
    try:
        def exchange(frame: Frame) -> list[Frame]:
            link.send([frame])
            out = []
            while (fr := link.poll()) is not None:
                out.append(fr)
            return out

        yield exchange
    finally:
        link.close()


@pytest.fixture(params=["python", "c-core"])
def exchange(request: pytest.FixtureRequest) -> Iterator[Exchange]:
    yield from (_python_target() if request.param == "python" else _c_core())


def _config_frame(param_id: int, bits: int) -> Frame:
    return Frame(CONFIG_PARAM_ID, bytes([param_id]) + struct.pack("<I", bits), False)


def _ack(frames: list[Frame]) -> ConfigAck:
    dec = FrameCodec("canfd").decoder(ordered=False)
    acks = [m for m in (dec.feed(f) for f in frames) if isinstance(m, ConfigAck)]
    assert len(acks) == 1, frames
    return acks[0]


def _bits(x: float) -> int:
    return int(struct.unpack("<I", struct.pack("<f", x))[0])


def test_non_finite_config_param_rejected_with_status_and_echo(exchange: Exchange) -> None:
    for pid in ParamId:
        for bits in BAD_BITS:
            frames = exchange(_config_frame(int(pid), bits))
            assert frames[0].data[1:5] == struct.pack("<I", bits), (pid, hex(bits))  # echoed bit for bit
            ack = _ack(frames)
            assert ack.param_id == pid and ack.status == int(Status.INVALID_CONFIG), (pid, hex(bits))
    ok = _ack(exchange(_config_frame(int(ParamId.RS), _bits(1.5))))  # still serving, values unchanged
    assert ok.status == int(Status.OK) and ok.value == 1.5


def test_out_of_range_config_param_rejected(exchange: Exchange) -> None:
    for pid, value in ((ParamId.RS, -1.0), (ParamId.POLE_PAIRS, 2.5), (ParamId.TS, 0.0), (ParamId.LD, 3e38)):
        ack = _ack(exchange(_config_frame(int(pid), _bits(value))))
        assert ack.status == int(Status.INVALID_CONFIG), pid


def test_ts_longer_than_a_command_carries_is_rejected(exchange: Exchange) -> None:
    """A Ts above the duration field (1048575 ns) is refused; the target keeps its Ts and answers the next
    Measurement with a full-period zero vector it can encode."""
    codec = FrameCodec("canfd")
    longest = MAX_DURATION_NS * 1e-9
    for ts in (2e-3, longest * 1.0001, 0.05):
        assert _ack(exchange(_config_frame(int(ParamId.TS), _bits(ts)))).status == int(Status.INVALID_CONFIG), ts
    assert _ack(exchange(_config_frame(int(ParamId.TS), _bits(1e-3)))).status == int(Status.OK)
    meas = Measurement(seq=3, i_a=0.0, i_b=0.0, i_c=0.0, theta_e=0.0, omega_m=0.0, vdc=300.0, status=0)
    dec = codec.decoder(ordered=False)
    replies = [m for f in codec.encode(meas) for fr in exchange(f) if (m := dec.feed(fr)) is not None]
    assert len(replies) == 1 and isinstance(replies[0], Command)
    assert replies[0].seq == 3 and replies[0].durations_ns == (1_000_000,)


def _cfg(ts_s: float) -> RunConfig:
    sc = load_scenario("steady").with_overrides(settle_s=0.0, duration_s=0.01)
    return replace(RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc), ts_s=ts_s)


def test_ts_validated_against_the_frame_format() -> None:
    assert round(MAX_TS_S * 1e9) == MAX_DURATION_NS == 1_048_575
    assert _cfg(1.048575e-3).ts_ns == MAX_DURATION_NS  # the longest period a Command carries
    for ts in (1.048576e-3, 1.1e-3, 5e-3, math.nan):
        with pytest.raises(ParameterError, match=r"--ts must be between 5 µs and 1\.04857(5|6) ms .*1048575 ns"):
            _cfg(ts)


def test_cli_ts_above_the_frame_format_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    from pmsm_hil.app.cli.main import main

    assert main(["run", "--ts", "2e-3", "--duration", "0.01", "--no-log"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("hil: error: --ts must be between") and "1048575 ns" in err[0]


@pytest.mark.parametrize(("argv", "message"), [
    (["--controller", "mpcc", "--param", "lambda=1000"],
     "--param lambda: controller 'mpcc' does not use it (used by mptc1, mptc2)"),
    (["--controller", "dsvm-20", "--param", "t_thr=8e-6"],
     "--param t_thr: controller 'dsvm-20' does not use it (used by hv-mpfc)"),
    (["--controller", "mpcc", "--param", "t_mpw=1e-6"],
     "--param t_mpw: controller 'mpcc' does not use it (no controller of the reference firmware reads it)"),
])
def test_cli_param_the_controller_does_not_use_exits_2(argv: list[str], message: str,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    from pmsm_hil.app.cli.main import main

    assert main(["run", *argv, "--duration", "0.01", "--no-log"]) == 2
    assert capsys.readouterr().err.strip() == f"hil: error: {message}"


def test_params_the_controller_uses_pass() -> None:
    check_params_used("mpcc", {"ld": 0.01, "id_ref": -1.0})  # the shared step's: every controller
    check_params_used("hv-mpfc", ["t_thr", "zero_select", "dt_comp", "t_dead"])
    check_params_used("external", {"lambda": 1.0, "t_mpw": 1e-6})  # a foreign firmware's own controller
    with pytest.raises(ParameterError, match="unknown controller parameter 'nope'"):
        check_params_used("mpcc", ["nope"])


def test_sweep_point_with_an_unused_param_names_the_grid(capsys: pytest.CaptureFixture[str]) -> None:
    from pmsm_hil.app.cli.main import main

    assert main(["sweep", "--grid", "controller=mpcc,mptc2", "--grid", "param.lambda=500", "--duration",
                 "0.01"]) == 2
    err = capsys.readouterr().err
    assert "--grid param.lambda: --param lambda: controller 'mpcc' does not use it (used by mptc1, mptc2)" in err


@pytest.mark.parametrize(("motor", "controller", "needs", "fits"), [
    ("im-2k2", "mpcc", "ld, lq, psi_f", "im-foc"),
    ("niu2020-ipmsm", "im-foc", "rr, lsigma, lm, psi_r_ref", "mpcc, fcs-mpc-1"),
])
def test_a_controller_for_another_kind_of_machine_is_refused(motor: str, controller: str, needs: str,
                                                             fits: str) -> None:
    from pmsm_hil.hil.presets_loader import load_motor
    from pmsm_hil.hil.runner.scenario import load_scenario

    with pytest.raises(ParameterError, match=f"controller '{controller}' needs the machine model parameter.s. "
                                             f"{needs}, which motor '{motor}' .* \\(controllers for it: {fits}"):
        RunConfig(motor=load_motor(motor), scenario=load_scenario("steady"), controller=controller)
    for fine in ("off", "external"):  # no model, or a foreign firmware's own
        RunConfig(motor=load_motor(motor), scenario=load_scenario("steady"), controller=fine)


@pytest.mark.parametrize(("param", "message"), [
    ("rs=1e-46", "--param rs=1e-46: rounds to 0 in float32 (the target receives 0)"),
    ("lambda=-1e-50", "--param lambda=-1e-50: rounds to 0 in float32"),
    ("lambda=1e39", "--param lambda=1e+39: beyond the float32 range"),
    ("ld=1e-45", "--param ld=1e-45: the controller's model would be singular: ld must be > 0 and a normal float32"),
    ("lq=0", "--param lq=0.0: the controller's model would be singular"),
    ("ld=-0.001", "--param ld=-0.001: the controller's model would be singular"),
])
def test_a_param_the_target_cannot_hold_or_a_singular_model_exits_2(param: str, message: str,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    from pmsm_hil.app.cli.main import main

    assert main(["run", "--param", param, "--duration", "0.01", "--no-log"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"hil: error: {message}") and len(err.splitlines()) == 1, err


def test_small_but_representable_params_pass() -> None:
    cfg = RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=load_scenario("steady"),
                    controller_params={"rs": 0.0, "id_ref": 1e-44, "ld": 2e-38})
    assert cfg.resolved_params() == {ParamId.RS: 0.0, ParamId.ID_REF: 1e-44, ParamId.LD: 2e-38}
