"""Hypothesis strategies for protocol messages within their encodable ranges."""

from __future__ import annotations

import math

from hypothesis import strategies as st

from pmsm_hil.protocol import Command, ConfigAck, ConfigParam, Fault, Heartbeat, Measurement, Setpoint

u8 = st.integers(0, 255)
u16 = st.integers(0, 0xFFFF)
f32 = st.floats(width=32, allow_nan=False, allow_infinity=False)

measurements = st.builds(
    Measurement,
    seq=u16,
    i_a=st.floats(-32.768, 32.767),
    i_b=st.floats(-32.768, 32.767),
    i_c=st.floats(-32.768, 32.767),
    theta_e=st.floats(0.0, 2 * math.pi, exclude_max=True),
    omega_m=st.floats(-655.36, 655.34),
    vdc=st.floats(0.0, 655.35),
    status=u8,
)


@st.composite
def commands(draw: st.DrawFn) -> Command:
    n = draw(st.integers(1, 3))
    return Command(
        draw(u16),
        tuple(draw(st.lists(st.integers(0, 63), min_size=n, max_size=n))),
        tuple(draw(st.lists(st.integers(0, 2**20 - 1), min_size=n, max_size=n))),
        draw(u8),
        draw(u8),
        draw(st.integers(0, 2**32 - 1)),
        draw(u8),
        draw(st.booleans()),
    )


setpoints = st.builds(Setpoint, enable=st.booleans(), mode=st.integers(0, 1), reference=f32, controller_id=u8)
config_params = st.builds(ConfigParam, param_id=u8, value=f32)
config_acks = st.builds(ConfigAck, param_id=u8, value=f32, status=u8)
heartbeats = st.builds(Heartbeat, node=st.integers(0, 1), state=u8, counter=u8)
faults = st.builds(Fault, node=st.integers(0, 1), code=u8, detail=st.integers(0, 2**32 - 1))
any_message = st.one_of(measurements, commands(), setpoints, config_params, config_acks, heartbeats, faults)
