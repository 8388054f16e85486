"""The DUT contract: what the host requires of the target every period (docs/runner.md, "DUT contract"),
the findings when it is broken, and how a run ends (end codes, the exit codes of `hil run`).

Per period k (seq = k mod 65536) the target sends exactly one Command echoing seq, within the lockstep
timeout (lockstep) or before the next period start (real time), with state codes of the machine
(0..2^legs − 1) and durations summing to Ts (mirrored: 2·(d0+…+d(n−2)) + d(n−1) = Ts), or (duty-cycle
form) one duty 0..1 per leg of the machine: a NaN or out-of-range duty is a finding, never a silent zero
vector. Frames the decoder rejects (wrong length, impossible values, parts that do not assemble) count
against the period they arrive in. A reply with another seq (a future one, or a second/late answer) is a
violation and never displaces the genuine reply.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import Final

from pmsm_hil.protocol.messages import Command


class EndCode(IntEnum):
    """How a run ended = the exit code of `hil run` (usage errors exit 2 before any run starts)."""

    COMPLETED = 0
    INTERNAL_ERROR = 1
    USAGE_ERROR = 2
    SAFETY_STOP = 3  # watchdog, plant trip, target fault, safe stop not confirmed (safe_stop.py)
    DUT_VIOLATION = 4
    INTERRUPTED = 130


#: Rules of the contract (the `rule` of a `Violation`).
MISSING: Final = "missing"  # no Command for the period in time
SEQUENCE: Final = "sequence"  # a Command whose seq is not the period's (future, stale, or a second answer)
STATE_CODE: Final = "state_code"  # a state code outside the machine's 0..2^legs − 1
DURATIONS: Final = "durations"  # durations that do not fill Ts
FRAME: Final = "frame"  # a frame the decoder rejected (length, value, assembly)
DUTY: Final = "duty"  # a duty-cycle Command with a duty outside 0..1, NaN, another leg count than the machine's
#                       (n_duties 4 or 200 too), or both forms set (duties and a switching sequence)
RULES: Final = (MISSING, SEQUENCE, STATE_CODE, DURATIONS, FRAME, DUTY)


@dataclass(frozen=True, slots=True)
class Violation:
    """One finding: period index, the seq expected, the rule, the frame (or message) concerned, the detail."""

    period: int
    seq: int
    rule: str
    frame: str
    detail: str

    def message(self) -> str:
        """One line naming period, seq, rule, frame and detail."""
        return f"DUT contract violation at period {self.period} (seq {self.seq}): {self.rule}: {self.detail} " \
               f"[{self.frame}]"

    def as_dict(self) -> dict[str, object]:
        """JSON form (metrics.json `dut_violations`)."""
        return {"period": self.period, "seq": self.seq, "rule": self.rule, "frame": self.frame,
                "detail": self.detail}


#: the `duty` finding of a Command sent with n_duties 0: its sender set both forms
BOTH_FORMS_ON_WIRE: Final = ("both forms set: duties and a switching sequence (sent as a duty Command with n_duties "
                             "0); a Command carries one")


def describe(cmd: Command) -> str:
    """Short text of a Command for a finding."""
    if cmd.both_forms and not cmd.duties:
        return f"Command seq={cmd.seq} n_duties=0 (both forms)"
    if cmd.duties:
        more = f", … {len(cmd.duties)} in all" if len(cmd.duties) > 6 else ""
        return f"Command seq={cmd.seq} duties=({', '.join(f'{d:.6g}' for d in cmd.duties[:6])}{more})"
    mirror = ", mirror" if cmd.mirror else ""
    return f"Command seq={cmd.seq} states={cmd.states} durations_ns={cmd.durations_ns}{mirror}"


def check_duties(duties: tuple[float, ...], legs: int) -> tuple[str, str] | None:
    """(DUTY, detail) when a duty-cycle Command cannot be applied to a machine with `legs` legs, else None."""
    if len(duties) != legs:
        return DUTY, f"{len(duties)} duties for a machine with {legs} legs"
    for j, d in enumerate(duties):
        if math.isnan(d):
            return DUTY, f"duty {j} is NaN"
        if not 0.0 <= d <= 1.0:
            return DUTY, f"duty {j} = {d:g} outside 0..1"
    return None


def check_command(cmd: Command, ts_ns: int, max_state: int) -> tuple[str, str] | None:
    """(rule, detail) when the Command's sequence (or duties) cannot be applied, else None."""
    if cmd.both_forms and not cmd.duties:
        return DUTY, BOTH_FORMS_ON_WIRE
    if cmd.duties and (cmd.states or cmd.durations_ns):
        return DUTY, (f"both forms set: {len(cmd.duties)} duties and a switching sequence of {len(cmd.states)} "
                      "state(s); a Command carries one")
    if cmd.duties:
        return check_duties(cmd.duties, max_state.bit_length())
    for j, code in enumerate(cmd.states):
        if not 0 <= code <= max_state:
            return STATE_CODE, f"state {j} = {code} outside 0..{max_state}"
    d = cmd.durations_ns
    if any(x < 0 for x in d):
        return DURATIONS, f"negative duration in {d}"
    if cmd.mirror and len(d) >= 2:
        total = 2 * sum(d[:-1]) + d[-1]
        if total != ts_ns:
            return DURATIONS, f"mirrored durations fill {total} ns (2·(d0+…+d(n−2)) + d(n−1)), Ts = {ts_ns} ns"
    elif sum(d) != ts_ns:
        return DURATIONS, f"durations sum to {sum(d)} ns, Ts = {ts_ns} ns"
    return None


__all__ = ["DURATIONS", "DUTY", "FRAME", "MISSING", "RULES", "SEQUENCE", "STATE_CODE", "EndCode", "Violation",
           "check_command", "check_duties", "describe"]
