"""A foreign target, written as a user would: python-can (the documented `hilserial` interface) + cantools +
src/pmsm_hil/protocol/hil.dbc, no project code. Misbehaves on request so the host's DUT contract can be tested.

Usage: python foreign_target.py PORT LOGFILE [RULE=PERIOD ...]
Rules: skip (no reply), future_seq (reply with seq + 1 instead), bad_sum (durations 1 ns short),
bad_state (state code 9), second (two replies), bad_length (a 19-byte Command frame), lose (the reply lost on the
wire: its link sequence number used up, nothing sent), fault (a FaultTarget
frame), silent (stop replying from then on), bad_ack (echo ConfigParam values + 1.0), ignore_disable (never
answer a disabling Setpoint with HeartbeatTarget idle: the safe stop is not confirmed; any PERIOD), duties (answer
with duty-cycle Commands, CmdDutyFd, duties 0.5: zero voltage; any PERIOD), nan_duty / range_duty (duty 1 sent as the
NaN / out-of-range code; with duties), duties6 (a dual three-phase machine: answer MeasFd6 with six distinct
duties near 0.5, all 13 carrier segments; with duties3 only three of them: a duty finding; any PERIOD),
n_duties4 / n_duties200 (a CmdDutyFd whose n_duties is 4 / 200: a duty finding, not a missing Command).
A disabling Setpoint is otherwise answered with HeartbeatTarget state idle (the confirmed safe stop).
Every frame received from the host is logged to LOGFILE as one JSON line, flushed at once.
The "controller": the zero vector for the whole period (a dyno run at low speed stays within its limits).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import can
import cantools

DBC = Path(__file__).resolve().parents[2] / "src" / "pmsm_hil" / "protocol" / "hil.dbc"
TS_NS = 100_000


def main() -> int:
    port, log_path = sys.argv[1], sys.argv[2]
    rules = {k: int(v) for k, _, v in (a.partition("=") for a in sys.argv[3:])}
    db = cantools.database.load_file(str(DBC))
    meas, cmd = db.get_message_by_name("MeasFd"), db.get_message_by_name("CmdFd")
    setpoint, param = db.get_message_by_name("Setpoint"), db.get_message_by_name("ConfigParam")
    ack, fault = db.get_message_by_name("ConfigAck"), db.get_message_by_name("FaultTarget")
    heartbeat = db.get_message_by_name("HeartbeatTarget")
    duty_cmd = db.get_message_by_name("CmdDutyFd")
    meas6 = db.get_message_by_name("MeasFd6")
    duty_full = 65520
    bus = can.Bus(interface="hilserial", channel=port)
    log = open(log_path, "w", encoding="utf-8")  # noqa: SIM115 - closed at exit

    def send(message: cantools.database.Message, strict: bool = True, **values: float) -> None:
        bus.send(can.Message(arbitration_id=message.frame_id, data=message.encode(values, strict=strict), is_fd=True,
                             is_extended_id=False))

    def reply(seq: int, duty1_raw: int = duty_full // 2) -> None:
        if "duties6" in rules:
            n = 3 if "duties3" in rules else 6
            send(duty_cmd, seq=seq, n_duties=n, **{f"duty{j}": 0.5 + 0.002 * (j - 2.5) for j in range(6)},
                 vector_id=0, candidates=0, exec_time_ns=1000, status=0)
            return
        if "duties" in rules:
            half = 0.5
            send(duty_cmd, seq=seq, n_duties=3, duty0=half, duty1=duty1_raw / duty_full, duty2=half, duty3=0, duty4=0,
                 duty5=0, vector_id=0, candidates=0, exec_time_ns=1000, status=0)
            return
        send(cmd, seq=seq, state0=0, state1=0, state2=0, n_states=1, duration0=TS_NS, duration1=0, duration2=0,
             vector_id=0, candidates=1, exec_time_ns=1000, status=0, mirror=0)

    k = beats = 0
    timeout = 30.0
    try:
        while True:
            msg = bus.recv(timeout=timeout)
            if msg is None:
                return 0
            if msg.arbitration_id == setpoint.frame_id:
                sp = setpoint.decode(msg.data, decode_choices=False)
                log.write(json.dumps({"frame": "Setpoint", "enable": int(sp["enable"])}) + "\n")
                if not sp["enable"]:
                    timeout = 0.3  # disabled: log what still comes, then end (a board would idle)
                    if "ignore_disable" not in rules:  # the confirmed safe stop
                        send(heartbeat, node=1, state=1, counter=beats & 0xFF)
                        beats += 1
            elif msg.arbitration_id == param.frame_id:
                p = param.decode(msg.data, decode_choices=False)
                value = p["value"] + (1.0 if "bad_ack" in rules else 0.0)
                send(ack, param_id=p["param_id"], value=value, status=0)
                log.write(json.dumps({"frame": "ConfigParam", "param_id": int(p["param_id"])}) + "\n")
            elif msg.arbitration_id in (meas.frame_id, meas6.frame_id):
                seq = int((meas if msg.arbitration_id == meas.frame_id else meas6).decode(msg.data,
                                                                                           decode_choices=False)["seq"])
                log.write(json.dumps({"frame": "Measurement", "seq": seq}) + "\n")
                if rules.get("silent", 1 << 30) <= k or rules.get("skip") == k:
                    pass
                elif rules.get("lose") == k:  # sent, and lost on the wire: its link sequence number is used up
                    wire = bus._state  # type: ignore[attr-defined]  # the C link's state (loop_serial.c, loop_udp.c)
                    counter = getattr(wire, "framer", wire)  # the serial link keeps it in its framer
                    counter.tx_seq = (counter.tx_seq + 1) & 0xFF
                elif rules.get("future_seq") == k:
                    reply((seq + 1) & 0xFFFF)
                elif rules.get("bad_sum") == k:
                    send(cmd, seq=seq, state0=0, state1=0, state2=0, n_states=1, duration0=TS_NS - 1, duration1=0,
                         duration2=0, vector_id=0, candidates=1, exec_time_ns=1000, status=0, mirror=0)
                elif rules.get("bad_state") == k:
                    send(cmd, seq=seq, state0=9, state1=0, state2=0, n_states=1, duration0=TS_NS, duration1=0,
                         duration2=0, vector_id=0, candidates=1, exec_time_ns=1000, status=0, mirror=0)
                elif rules.get("nan_duty") == k:
                    reply(seq, 65535)
                elif rules.get("range_duty") == k:
                    reply(seq, 65534)
                elif k in (rules.get("n_duties4"), rules.get("n_duties200")):  # a duty count of no machine
                    send(duty_cmd, strict=False, seq=seq, n_duties=4 if rules.get("n_duties4") == k else 200,
                         **{f"duty{j}": 0.5 for j in range(6)}, vector_id=0, candidates=0, exec_time_ns=1000, status=0)
                elif rules.get("bad_length") == k:
                    bus.send(can.Message(arbitration_id=cmd.frame_id, data=bytes(24), is_fd=True,
                                         is_extended_id=False))
                    reply(seq)
                else:
                    reply(seq)
                    if rules.get("second") == k:
                        reply(seq)
                if rules.get("fault") == k:
                    send(fault, node=1, code=1, detail=7)
                k += 1
            else:
                log.write(json.dumps({"frame": hex(msg.arbitration_id)}) + "\n")
            log.flush()
    finally:
        log.close()
        bus.shutdown()


if __name__ == "__main__":
    sys.exit(main())
