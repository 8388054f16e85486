"""pmsm_hil.protocol: frame protocol (hil.dbc), hot-path codec, links and link budget.

Links live in `pmsm_hil.protocol.links` (imported on demand: they pull in python-can and pyserial)."""

from pmsm_hil.protocol.codec import PROFILES, FrameCodec, FrameDecoder, Profile, decode_frame, decode_message
from pmsm_hil.protocol.errors import DecodeError, EncodeError, LinkError, LinkSpecError, ProtocolError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.messages import (
    Command,
    ConfigAck,
    ConfigParam,
    Fault,
    Heartbeat,
    Measurement,
    Measurement6,
    Message,
    Setpoint,
)

__all__ = [
    "PROFILES",
    "Command",
    "ConfigAck",
    "ConfigParam",
    "DecodeError",
    "EncodeError",
    "Fault",
    "Frame",
    "FrameCodec",
    "FrameDecoder",
    "Heartbeat",
    "LinkError",
    "LinkSpecError",
    "Measurement",
    "Measurement6",
    "Message",
    "Profile",
    "ProtocolError",
    "Setpoint",
    "decode_frame",
    "decode_message",
]
