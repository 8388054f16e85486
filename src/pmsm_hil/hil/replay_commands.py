"""The switching sequence the period loop applies in each period, from the Commands it received: the replay's
mirror of src/pmsm_hil/hil/runner/c/loop.c.

In the loop, period k samples the plant at t = k·Ts (the period's record and Measurement k), advances the plant over
[k·Ts, (k+1)·Ts) with the Command in force, then takes Command k (the reply to Measurement k), which is in force over
period k + 1. Period 0 has no Command yet: the zero vector (state 0 for Ts). So Command k drives period k + 1, and the
plant state at t = (k+2)·Ts is the first one it changes. A duty-cycle Command is the carrier comparison of the period
it drives (`pwm.applied_sequence`; under `--pwm-update double` the rising half in even periods, the falling half in
odd ones). A Command the run did not apply (a DUT-contract finding or none at all: the period record's `missed`) is
replaced as the run's miss policy says: the zero vector (`zero`) or the Command in force (`hold`)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Final

from pmsm_hil.hil.errors import InputFileError
from pmsm_hil.hil.machine import MachineLayout
from pmsm_hil.hil.pwm import applied_sequence, carrier_half
from pmsm_hil.protocol.messages import Command

SEQ_MOD: Final = 1 << 16  # Command.seq wraps at 65536
#: (states, durations [ns]) of one period
PeriodSequence = tuple[tuple[int, ...], tuple[int, ...]]


@dataclass(frozen=True, slots=True)
class AppliedPeriods:
    """What the loop applied: `sequences[k]` over period k (period 0 the zero vector), `commands` Commands applied,
    `gaps` Commands missing from the capture and held as the zero vector (`--allow-gaps`), `run_misses` Commands the
    run itself did not apply (its miss policy in their place)."""

    sequences: list[PeriodSequence]
    commands: int
    gaps: int
    run_misses: int


def zero_vector(ts_ns: int) -> PeriodSequence:
    """State 0 (every lower switch on) for the whole period of `ts_ns` ns."""
    return (0,), (ts_ns,)


def _command_sequence(cmd: Command, period: int, ts_ns: int, layout: MachineLayout, pwm_update: str,
                      where: str) -> PeriodSequence:
    """The sequence Command `cmd` gives period `period`; InputFileError naming its seq unless the loop would apply it:
    the machine's duty count, each duty in 0..1, state codes within the machine's, durations filling Ts."""
    if cmd.duties:
        if len(cmd.duties) != layout.legs:
            raise InputFileError(f"{where}Command seq {cmd.seq}: {len(cmd.duties)} duty cycles for a "
                                 f"{layout.legs}-phase motor")
        bad = next((j for j, d in enumerate(cmd.duties) if not (math.isfinite(d) and 0.0 <= d <= 1.0)), None)
        if bad is not None:
            raise InputFileError(f"{where}Command seq {cmd.seq}: duty {bad} is {cmd.duties[bad]} (outside 0..1)")
        return applied_sequence(cmd, ts_ns, carrier_half(pwm_update, period))
    states, durations = cmd.expanded()
    bad_code = next((s for s in states if not 0 <= s <= layout.max_state_code), None)
    if bad_code is not None:
        raise InputFileError(f"{where}Command seq {cmd.seq}: state code {bad_code} beyond "
                             f"0..{layout.max_state_code} ({layout.legs}-phase motor)")
    if sum(durations) != ts_ns:
        raise InputFileError(f"{where}Command seq {cmd.seq}: durations sum to {sum(durations)} ns, "
                             f"expected Ts = {ts_ns} ns (--ts)")
    return states, durations


def _step(where: str, seq: int, previous: int | None, expected: int) -> int:
    """How many positions Command `seq` lies after the last one (`previous`, None before the first; `expected` the
    seq due next): 1 when it follows, more across a gap; InputFileError for a repeated or earlier seq."""
    step = (seq - expected) % SEQ_MOD + 1
    if step == 1 or previous is None:
        return step
    if seq == previous:
        raise InputFileError(f"{where}Command seq {seq} appears twice in a row (a duplicated capture?)")
    if step > SEQ_MOD // 2:
        raise InputFileError(f"{where}Command seq {seq} after seq {previous}: goes back (a reversed, merged or "
                             "duplicated capture?)")
    return step


def applied_periods(commands: Iterable[Command], *, ts_ns: int, layout: MachineLayout, source: str = "",
                    pwm_update: str = "single", allow_gaps: bool = False, first_seq: int | None = 0,
                    run_misses: Iterable[int] = (), miss_policy: str = "zero") -> AppliedPeriods:
    """The sequence of each period the loop ran on `commands` (in the order received), see the module docstring.

    `first_seq`: the seq of the run's first Command (0: the capture holds the run from its start; None: the
    capture's first Command, a capture started during a run). Commands must follow each other by one seq (mod
    65536): a repeated or earlier seq is an InputFileError naming it; a missing one too (the first missing seq named)
    unless `allow_gaps`, which holds each missing Command as the zero vector and counts it. `run_misses`: the
    periods k whose Command the run did not apply (its records' `missed`): replaced per `miss_policy` (zero, hold),
    not checked, and not a gap when absent. `source` prefixes every error (e.g. "CAN log PATH: ")."""
    misses = frozenset(run_misses)
    sequences: list[PeriodSequence] = [zero_vector(ts_ns)]
    n_cmds = n_gaps = n_missed = 0
    previous: int | None = None
    expected = first_seq
    in_force: Command | None = None  # None: the zero vector

    def fill(k: int) -> None:
        """Period k + 1 for a Command k that did not come or was not applied: the zero vector, or under the run's
        `hold` policy the Command in force (duty cycles compared with this period's carrier half)."""
        nonlocal n_gaps, n_missed, in_force
        if k in misses and miss_policy == "hold":
            n_missed += 1
            sequences.append(sequences[-1] if in_force is None or not in_force.duties else
                             _command_sequence(in_force, k + 1, ts_ns, layout, pwm_update, source))
            return
        if k in misses:
            n_missed += 1
        else:
            n_gaps += 1
        in_force = None
        sequences.append(zero_vector(ts_ns))

    for cmd in commands:
        if expected is None:
            expected = cmd.seq
        step = _step(source, cmd.seq, previous, expected)
        first_missing = len(sequences) - 1
        unexplained = [k for k in range(first_missing, first_missing + step - 1) if k not in misses]
        if unexplained and not allow_gaps:
            gap_seq = (expected + unexplained[0] - first_missing) % SEQ_MOD
            after = f"seq {cmd.seq} follows seq {previous}" if previous is not None else \
                f"the capture's first Command is seq {cmd.seq}"
            raise InputFileError(f"{source}Command seq {gap_seq} missing ({after}): the capture lost "
                                 f"{len(unexplained)} Command(s); --allow-gaps replays them as the zero vector")
        for k in range(first_missing, first_missing + step - 1):
            fill(k)
        k = len(sequences) - 1
        previous, expected = cmd.seq, (cmd.seq + 1) % SEQ_MOD
        if k in misses:
            fill(k)
            continue
        sequences.append(_command_sequence(cmd, k + 1, ts_ns, layout, pwm_update, source))
        in_force = cmd
        n_cmds += 1
    return AppliedPeriods(sequences, n_cmds, n_gaps, n_missed)


__all__ = ["SEQ_MOD", "AppliedPeriods", "applied_periods", "zero_vector"]
