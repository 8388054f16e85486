"""Words for what the native loop reports as numbers: its DUT-contract findings (`Violation`s worded as
`TargetClient` and `ClosedLoop` word them) and the exceptions behind its internal-error endings."""

from __future__ import annotations

from typing import Any

from pmsm_hil.hil.errors import ParameterError, PlantFaultError
from pmsm_hil.hil.plant_base import MAX_LOAD_BREAKPOINTS
from pmsm_hil.hil.runner.contract import BOTH_FORMS_ON_WIRE, RULES, Violation, describe
from pmsm_hil.protocol.codec_duty import duty_value
from pmsm_hil.protocol.errors import EncodeError
from pmsm_hil.protocol.messages import Command


def _command(f: Any) -> Command:
    if int(f.n_duties):
        return Command(seq=int(f.cmd_seq), states=(), durations_ns=(),
                       duties=tuple(duty_value(int(r)) for r in f.duty_raw[0:min(int(f.n_duties), len(f.duty_raw))]))
    n = int(f.n_states)
    return Command(seq=int(f.cmd_seq), states=tuple(int(s) for s in f.states[0:n]),
                   durations_ns=tuple(int(d) for d in f.durations_ns[0:n]), mirror=bool(f.mirror))


def violation(f: Any, lib: Any, limit: str) -> Violation:
    """The `Violation` of one nl_finding_t; `limit`: how a missing Command was waited for."""
    k = int(f.period)
    what, v = int(f.what), [int(x) for x in f.v]
    frame = describe(_command(f)) if f.has_cmd else "frames from the target"
    if what == lib.NL_WHAT_MISSING:
        frame, detail = "Command", f"no Command for seq {v[0]} {limit}"
    elif what == lib.NL_WHAT_SECOND:
        detail = f"a second Command for seq {v[0]}"
    elif what == lib.NL_WHAT_OTHER_SEQ:
        detail = f"seq {v[0]} while the period's seq is {v[1]}"
    elif what == lib.NL_WHAT_DECODER_SEQ:
        detail = (f"{v[0]} frame(s) with an old or repeated seq (stale {v[1]}, duplicate {v[2]}, out_of_order {v[3]}, "
                  f"mixed_seq {v[4]})")
    elif what == lib.NL_WHAT_DECODER_FRAME:
        detail = f"{v[0]} frame(s) rejected by the decoder (bad_length {v[1]}, bad_value {v[2]})"
    elif what == lib.NL_WHAT_STATE_CODE:
        detail = f"state {v[0]} = {v[1]} outside 0..{v[2]}"
    elif what == lib.NL_WHAT_DUTY_COUNT:
        detail = f"{v[0]} duties for a machine with {v[1]} legs"
    elif what == lib.NL_WHAT_BOTH_FORMS:
        frame = describe(Command(seq=int(f.cmd_seq), states=(), durations_ns=(), both_forms=True))
        detail = BOTH_FORMS_ON_WIRE
    elif what == lib.NL_WHAT_DUTY:
        d = duty_value(v[1])
        detail = f"duty {v[0]} is NaN" if d != d else f"duty {v[0]} = {d:g} outside 0..1"
    else:
        cmd = _command(f)
        if cmd.mirror and len(cmd.states) >= 2:
            detail = f"mirrored durations fill {v[0]} ns (2·(d0+…+d(n−2)) + d(n−1)), Ts = {v[1]} ns"
        else:
            detail = f"durations sum to {v[0]} ns, Ts = {v[1]} ns"
    return Violation(k, k & 0xFFFF, RULES[int(f.rule)], frame, detail)


def internal_error(res: Any, lib: Any, legs: int) -> Exception:
    """The exception the Python loop raises where the native loop ended with a plant or codec error."""
    if res.end == lib.NL_END_ENCODE_ERROR:
        names = ["theta_e", *("i_a", "i_b", "i_c", "i_u", "i_v", "i_w")[:legs], "omega_m", "vdc"]
        name, value = names[int(res.encode_field)], float(res.encode_value)
        if name == "theta_e":
            kind = "Measurement6" if legs == 6 else "Measurement"
            return EncodeError(f"{kind}.theta_e={value!r} is not a finite number")
        return EncodeError(f"Measurement.{name}={value!r} is not a number")
    if int(res.plant_rc) == lib.NL_PLANT_E_BREAKPOINTS:
        return ParameterError(f"load profile has {int(res.plant_detail)} breakpoints inside one control period "
                              f"(at most {MAX_LOAD_BREAKPOINTS})")
    return PlantFaultError(f"plant kernel rejected the period (code {int(res.plant_rc)})")
