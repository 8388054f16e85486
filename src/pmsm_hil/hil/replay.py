"""Offline replay: drive the plant (dyno mode) with switching commands read from a CSV file.

A motor with ``lls > 0`` is dual three-phase: the input then has the columns ``sa1,sb1,sc1,sa2,sb2,sc2``
(set 1 A, B, C and set 2 U, V, W) or the sequence form with 6-bit codes [S_A S_B S_C S_U S_V S_W]
(0..63), and the output has `OUTPUT_COLUMNS6`."""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from pmsm_hil.hil.atomic_write import atomic_path, refuse_inputs
from pmsm_hil.hil.errors import InputFileError, ParameterError, SequenceError
from pmsm_hil.hil.machine import DUAL_THREE_PHASE, THREE_PHASE, MachineLayout, machine_for
from pmsm_hil.hil.machine_params import MachineParams
from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.plant import MAX_SUBINTERVALS
from pmsm_hil.hil.plant_base import PlantBase
from pmsm_hil.hil.replay_commands import PeriodSequence, applied_periods

OUTPUT_COLUMNS = THREE_PHASE.replay_columns
OUTPUT_COLUMNS6 = DUAL_THREE_PHASE.replay_columns


@dataclass(frozen=True, slots=True)
class ReplayCommand:
    """One control period of the input: state codes and durations [ns]."""

    states: tuple[int, ...]
    durations_ns: tuple[int, ...]


def _parse_bit(text: str, row: int, column: str) -> int:
    if text.strip() not in ("0", "1"):
        raise InputFileError(f"row {row}, column '{column}': expected 0 or 1, got {text!r}")
    return int(text)


def read_commands(path: Path, ts_ns: int, *, layout: MachineLayout = THREE_PHASE) -> Iterator[ReplayCommand]:
    """Yield the commands of a replay CSV (header required; rows numbered from 1 after the header).

    Forms: ``sa,sb,sc`` (one state for the whole period) or ``s0,t0,s1,t1,s2,t2`` (state codes and
    durations [s] summing to Ts; unused slots empty). Six phases: ``sa1,sb1,sc1,sa2,sb2,sc2`` or the
    sequence form with codes 0..63 (`layout`: the machine's legs and largest state code). Row k drives period k.
    """
    legs = layout.replay_legs
    max_code = layout.max_state_code
    try:
        handle = path.open(newline="", encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputFileError(f"input file {path}: {exc.strerror}") from None
    with handle:
        reader = csv.reader(handle)
        header = [h.strip() for h in next(reader, [])]
        if not header:
            raise InputFileError(f"input file {path}: empty (a header row is required)")
        if header[:len(legs)] == list(legs):
            form = "legs"
        elif header[:2] == ["s0", "t0"]:
            form = "sequence"
            slots = len(header) // 2
            expected = [f"{p}{k}" for k in range(slots) for p in ("s", "t")]
            if header != expected or slots > MAX_SUBINTERVALS:
                raise InputFileError(
                    f"input file {path}: sequence header must be s0,t0,s1,t1,... (≤ {MAX_SUBINTERVALS} slots), "
                    f"got {','.join(header)}")
        else:
            raise InputFileError(f"input file {path}: header must be '{','.join(legs)}' or 's0,t0,s1,t1,...' "
                                 f"({layout.legs}-phase motor), got {','.join(header)}")
        for row_no, row in enumerate(reader, start=1):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != len(header):
                raise InputFileError(f"row {row_no}: expected {len(header)} columns, got {len(row)}")
            if form == "legs":
                code = 0
                for k, column in enumerate(legs):
                    code = 2 * code + _parse_bit(row[k], row_no, column)
                yield ReplayCommand((code,), (ts_ns,))
            else:
                yield _parse_sequence_row(row, header, row_no, ts_ns, max_code)


def _parse_sequence_row(row: list[str], header: list[str], row_no: int, ts_ns: int,
                        max_code: int = 7) -> ReplayCommand:
    states: list[int] = []
    durs: list[int] = []
    for k in range(0, len(header), 2):
        s_text, t_text = row[k].strip(), row[k + 1].strip()
        if not s_text and not t_text:
            continue
        if not s_text or not t_text:
            missing = header[k] if not s_text else header[k + 1]
            raise InputFileError(f"row {row_no}, column '{missing}': empty while its pair is set")
        if not (s_text.isascii() and s_text.isdigit()) or not 0 <= int(s_text) <= max_code:
            raise InputFileError(
                f"row {row_no}, column '{header[k]}': state code must be 0..{max_code}, got {s_text!r}")
        try:
            t_val = float(t_text)
        except ValueError:
            raise InputFileError(f"row {row_no}, column '{header[k + 1]}': not a number: {t_text!r}") from None
        if not math.isfinite(t_val) or t_val < 0:
            raise InputFileError(f"row {row_no}, column '{header[k + 1]}': duration must be ≥ 0 s, got {t_text}")
        if t_val * 1e9 > ts_ns + 1:
            raise InputFileError(f"row {row_no}, column '{header[k + 1]}': duration {t_text} s is longer than "
                                 f"Ts = {ts_ns * 1e-9:.9g} s")
        states.append(int(s_text))
        durs.append(round(t_val * 1e9))
    if not states:
        raise InputFileError(f"row {row_no}: no state in any slot")
    total = sum(durs)
    if abs(total - ts_ns) > 1:
        raise InputFileError(f"row {row_no}: durations sum to {total * 1e-9:.9g} s, expected Ts = {ts_ns * 1e-9:.9g} s")
    durs[-1] += ts_ns - total  # absorb sub-ns rounding of the decimal durations
    return ReplayCommand(tuple(states), tuple(durs))


@dataclass(frozen=True, slots=True)
class ReplayResult:
    """A replay's counts: `periods` replayed (the output has periods + 1 rows), `commands` applied (CSV rows or
    Commands), `gaps` Commands missing from a capture held as the zero vector (`--allow-gaps`), `run_misses`
    Commands the run did not apply (its miss policy in their place)."""

    periods: int
    commands: int
    gaps: int = 0
    run_misses: int = 0


def plant_rows(plant: PlantBase, layout: MachineLayout, sequences: Sequence[PeriodSequence], *,
               where: str = "", before_period: Callable[[int], None] | None = None) -> list[tuple[float, ...]]:
    """The plant's replay row (`layout.replay_columns`) at the start of each period and after the last: the
    sequences applied one period each. `before_period(k)` runs before row k is sampled (the loop's reference
    change in dyno mode). ParameterError naming the row and column where the state is not finite (`where` added:
    the speed option), InputFileError for a sequence the plant refuses."""

    def _row(idx: int) -> tuple[float, ...]:
        values = tuple(float(v) for v in layout.replay_row(plant.sample()))
        if not all(math.isfinite(v) for v in values):
            col, value = next((c, v) for c, v in zip(layout.replay_columns, values, strict=True)
                              if not math.isfinite(v))
            raise ParameterError(f"row {idx}: the plant state is not finite ({col} = {value}){where}: "
                                 "the speed or the --set parameters are beyond the model")
        return values

    rows = []
    for idx, (states, durations) in enumerate(sequences):
        if before_period is not None:
            before_period(idx)
        rows.append(_row(idx))
        try:
            plant.advance(states, durations)
        except SequenceError as exc:
            raise InputFileError(f"row {idx + 1}: {exc}") from None
    rows.append(_row(len(sequences)))
    return rows


def write_rows(path: Path, layout: MachineLayout, rows: Sequence[tuple[float, ...]]) -> None:
    """The replay CSV: header `layout.replay_columns`, one row per period start (floats as repr), written through a
    temporary file (an existing file is replaced only by a complete one)."""
    with atomic_path(path, option="--output") as tmp, tmp.open("w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out)
        writer.writerow(layout.replay_columns)
        writer.writerows([repr(v) for v in row] for row in rows)


def replay(params: MachineParams, *, rpm: float, ts_s: float, input_path: Path, output_path: Path,
           theta0_rad: float = 0.0, allow_gaps: bool = False, pwm_update: str = "single") -> ReplayResult:
    """Replay the input through the plant in dyno mode at `rpm`; writes one row per period start and the end state.

    A replay CSV's row k drives period k. A CAN log (`replay_canlog.is_can_log`: .log, .asc, .blf, python-can .csv)
    drives the plant as the run's loop did (`replay_commands`): the zero vector in period 0, the capture's first
    Command in period 1 and each next one in the period after (duty cycles through the carrier of `pwm_update`);
    a missing Command is an error naming its seq unless `allow_gaps` (then the zero vector, counted).
    A motor with lls > 0 runs the dual three-phase plant (`Plant6`) and writes `OUTPUT_COLUMNS6`.
    The output is written through a temporary file and only if the replay produced valid rows: an input
    without command rows, an output that is the input, or a non-finite plant state raise InputFileError /
    ParameterError and leave an existing output untouched."""
    from pmsm_hil.hil.replay_canlog import is_can_log, read_log_commands

    refuse_inputs(output_path, [input_path], option="--output")
    machine = machine_for(params)
    layout = machine.layout
    plant = machine.build_plant(ts_s, DynoMechanics(rpm), theta0_rad=theta0_rad, trace_dt_s=None)
    if is_can_log(input_path):
        applied = applied_periods(read_log_commands(input_path), ts_ns=plant.ts_ns, layout=layout,
                                  source=f"CAN log {input_path}: ", pwm_update=pwm_update, allow_gaps=allow_gaps,
                                  first_seq=None)
        if not applied.commands:
            raise InputFileError(f"CAN log {input_path}: no Command frames (nothing to replay)")
        sequences = applied.sequences
        result = ReplayResult(len(sequences), applied.commands, applied.gaps)
    else:
        sequences = [(c.states, c.durations_ns) for c in read_commands(input_path, plant.ts_ns, layout=layout)]
        if not sequences:
            raise InputFileError(f"input file {input_path}: no command rows after the header (nothing to replay)")
        result = ReplayResult(len(sequences), len(sequences))
    rows = plant_rows(plant, layout, sequences, where=f" at --rpm {rpm:g}")
    write_rows(output_path, layout, rows)
    return result
