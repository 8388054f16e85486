"""Link budget: worst-case wire time of one control period (measurement up, command down).

Classic CAN, 11-bit id, n data bytes (bit stuffing worst case, 3-bit intermission included):
    bits = 47 + 8n + floor((34 + 8n - 1) / 4)
CAN FD, 11-bit id, BRS: nominal phase (SOF..BRS 17 bits + ≤ 4 stuff bits, CRC delimiter, ACK 2,
EOF 7, IFS 3 = 34 bits at the nominal rate; BRS and the CRC delimiter counted at the nominal rate,
conservatively) and data phase (ESI + DLC 5 bits + 8n + the remaining dynamic stuff bits
floor((22 + 8n - 1)/4) - 4, stuff count 4 bits, CRC 17 (n ≤ 16) or 21, fixed stuff bits
ceil((4 + crc)/4)) at the data rate.
Serial (8N1, 10 bits per byte): COBS(7-byte header + n + 2-byte CRC) + 0x00 delimiter; authenticated frames
(`auth`, src/pmsm_hil/protocol/links/auth.py) add their 6-byte trailer (freshness 2 + MAC 4) inside the COBS block (UDP:
inside the datagram).
UDP (one datagram per frame, CAN FD sized payloads): session id 4 + header + n + CRC 2 bytes of UDP payload, plus
UDP 8, IPv4 20, Ethernet header and FCS 18 (padded to the 64-byte minimum frame), preamble/SFD 8 and the
inter-frame gap 12 bytes on the wire, at `bitrate` (default for udp: 1 Gbit/s Ethernet). This is the wire only:
the host's network stack costs more (a loopback round trip is ~10 µs here, `hil bench loop` udp_floor).
Six-phase uses the reserved layouts (classic: + MeasC 8 bytes; FD/serial/udp: MeasFd6 24 bytes).
Commands: "states" (switching states: CmdA + CmdB + CmdC / CmdFd 20 bytes) or "duties" (duty-cycle form:
CmdDutyA + CmdDutyB + CmdDutyC, 3 × 8 bytes / CmdDutyFd 24 bytes).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, Literal

from pmsm_hil.protocol.errors import BudgetError
from pmsm_hil.protocol.layout import load_layouts
from pmsm_hil.protocol.links.auth import TRAILER
from pmsm_hil.protocol.links.wire import CRC_SIZE, HEADER_SIZE

LinkKind = Literal["can", "canfd", "serial", "udp"]
LINK_KINDS: tuple[LinkKind, ...] = ("can", "canfd", "serial", "udp")
#: the Command forms (`hil link-budget --command`)
COMMAND_FORMS: tuple[str, ...] = ("states", "duties")
DEFAULT_BITRATE = 1_000_000
#: udp: the Ethernet bit rate when none is given [bit/s]
DEFAULT_ETHERNET_BITRATE = 1_000_000_000
#: udp: bytes per datagram beyond the frame: session id 4 + CRC 2
UDP_FRAMING = 4 + 2
#: Ethernet: UDP 8 + IPv4 20 bytes in the Ethernet payload; header 14 + FCS 4; preamble/SFD 8 + inter-frame gap 12
UDP_IP_HEADERS = 8 + 20
ETHERNET_FRAME_OVERHEAD = 14 + 4
ETHERNET_WIRE_EXTRA = 8 + 12
ETHERNET_MIN_FRAME = 64
DEFAULT_DATA_BITRATE = 5_000_000
DEFAULT_BAUD = 3_000_000
MEAS_C_LENGTH = 8  # reserved 0x102: seq u16 + i_u, i_v, i_w int16
MEAS_FD6_LENGTH = 24  # reserved 0x109: 21 bytes used, next FD length 24


def can_frame_bits(n: int) -> int:
    """Worst-case bits of a classic CAN data frame with an 11-bit id and n data bytes (incl. IFS)."""
    return 47 + 8 * n + (34 + 8 * n - 1) // 4


def canfd_frame_bits(n: int) -> tuple[int, int]:
    """Worst-case (nominal-rate bits, data-rate bits) of an 11-bit-id CAN FD frame with BRS."""
    crc = 17 if n <= 16 else 21
    stuff_total = (22 + 8 * n - 1) // 4
    arb_stuff = (17 - 1) // 4
    nominal = 17 + arb_stuff + 1 + 2 + 7 + 3
    data = 5 + 8 * n + (stuff_total - arb_stuff) + 4 + crc + math.ceil((4 + crc) / 4)
    return nominal, data


def serial_frame_bytes(n: int, auth: bool = False) -> int:
    """Bytes on the line for one frame: COBS(header + payload [+ auth trailer] + CRC) + delimiter."""
    raw = HEADER_SIZE + n + (TRAILER if auth else 0) + CRC_SIZE
    return int(raw + max(1, math.ceil(raw / 254)) + 1)


def udp_frame_bytes(n: int, auth: bool = False) -> int:
    """Bytes on an Ethernet wire for one frame with n payload bytes sent as a UDP datagram [+ auth trailer]
    (module docstring)."""
    payload = HEADER_SIZE + n + (TRAILER if auth else 0) + UDP_FRAMING
    ethernet = max(payload + UDP_IP_HEADERS + ETHERNET_FRAME_OVERHEAD, ETHERNET_MIN_FRAME)
    return ethernet + ETHERNET_WIRE_EXTRA


@dataclass(frozen=True, slots=True)
class LinkBudget:
    """Result of `link_budget`; times in µs, rates in Hz, load in % of the control period."""

    link: str
    phases: int
    bitrate: int
    data_bitrate: int
    baud: int
    payloads_up: tuple[int, ...]
    payloads_down: tuple[int, ...]
    frames_per_period_up: int
    frames_per_period_down: int
    bits_up_worst: int
    bits_down_worst: int
    bits_per_period_worst: int
    wire_time_up_us: float
    wire_time_down_us: float
    wire_time_per_period_us: float
    max_rate_hz: float
    rate_hz: float | None
    bus_load_pct: float | None
    feasible: bool | None
    auth: bool = False

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        d = asdict(self)
        d["payloads_up"] = list(self.payloads_up)
        d["payloads_down"] = list(self.payloads_down)
        return d


def payloads(link: str, phases: int, command: str = "states") -> tuple[tuple[int, ...], tuple[int, ...]]:
    """Payload lengths per period (up = measurement, down = command in the `command` form), from the DBC."""
    lay = load_layouts()
    duty = command == "duties"
    if link == "can":
        up = [lay["MeasA"].length, lay["MeasB"].length] + ([MEAS_C_LENGTH] if phases == 6 else [])
        parts = ("CmdDutyA", "CmdDutyB", "CmdDutyC") if duty else ("CmdA", "CmdB", "CmdC")
        down = [lay[name].length for name in parts]
    else:
        up = [MEAS_FD6_LENGTH if phases == 6 else lay["MeasFd"].length]
        down = [lay["CmdDutyFd" if duty else "CmdFd"].length]
    return tuple(up), tuple(down)


def _positive(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise BudgetError(f"{name}={value!r} must be a positive number")


def link_budget(
    link: str,
    phases: int = 3,
    *,
    bitrate: int = DEFAULT_BITRATE,
    data_bitrate: int = DEFAULT_DATA_BITRATE,
    baud: int = DEFAULT_BAUD,
    rate_hz: float | None = None,
    auth: bool = False,
    command: str = "states",
) -> LinkBudget:
    """Worst-case budget of one control period on `link` ("can", "canfd", "serial" or "udp").

    `bitrate` is the (nominal) CAN bit rate [bit/s] (udp: the Ethernet bit rate), `data_bitrate` the CAN FD
    data-phase rate,
    `baud` the serial line rate (8N1). The closed loop sends measurement then command sequentially,
    so max_rate_hz = 1 / (up + down wire time), compute time excluded. bus_load_pct: CAN shares one
    medium (up + down)/Ts; serial and switched Ethernet are full duplex, max(up, down)/Ts. `auth`: serial and
    UDP frames carry the authentication trailer (CAN links are not authenticated)."""
    if link not in LINK_KINDS:
        raise BudgetError(f"link={link!r} unknown (expected one of {', '.join(LINK_KINDS)})")
    if phases not in (3, 6):
        raise BudgetError(f"phases={phases!r} (expected 3 or 6)")
    if command not in COMMAND_FORMS:
        raise BudgetError(f"command={command!r} unknown (expected one of {', '.join(COMMAND_FORMS)})")
    _positive("bitrate", bitrate)
    _positive("data_bitrate", data_bitrate)
    _positive("baud", baud)
    if rate_hz is not None:
        _positive("rate_hz", rate_hz)
    up, down = payloads(link, phases, command)

    def cost(ns: tuple[int, ...]) -> tuple[int, float]:
        bits = 0
        seconds = 0.0
        for n in ns:
            if link == "can":
                b = can_frame_bits(n)
                bits += b
                seconds += b / bitrate
            elif link == "canfd":
                nom, dat = canfd_frame_bits(n)
                bits += nom + dat
                seconds += nom / bitrate + dat / data_bitrate
            elif link == "udp":
                b = 8 * udp_frame_bytes(n, auth)
                bits += b
                seconds += b / bitrate
            else:
                b = 10 * serial_frame_bytes(n, auth)
                bits += b
                seconds += b / baud
        return bits, seconds * 1e6

    bits_up, t_up = cost(up)
    bits_down, t_down = cost(down)
    t_period = t_up + t_down
    load = None
    feasible = None
    if rate_hz is not None:
        busy = max(t_up, t_down) if link in ("serial", "udp") else t_period  # full duplex
        load = busy * 1e-6 * rate_hz * 100.0
        feasible = t_period * 1e-6 * rate_hz <= 1.0
    return LinkBudget(
        link,
        phases,
        int(bitrate),
        int(data_bitrate),
        int(baud),
        up,
        down,
        len(up),
        len(down),
        bits_up,
        bits_down,
        bits_up + bits_down,
        t_up,
        t_down,
        t_period,
        1e6 / t_period,
        rate_hz,
        load,
        feasible,
        auth and link in ("serial", "udp"),
    )
