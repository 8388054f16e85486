"""A board description (TOML, src/pmsm_hil/sim_target/stm32g4/boards/*.toml): the part, the HSE, the PWM timer and
its phase channels, the analog front end (which ADC channel sees which phase current or the DC-link voltage,
with offset, gain and noise), the encoder and the hall sensors, so that a user's board is a file, not code.
`load_board(name or path)` checks every field and names the bad one."""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pmsm_hil.sim_target.stm32g4.part import Part, part_named
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError

BOARDS_DIR = Path(__file__).with_name("boards")
DEFAULT_BOARD = "nucleo_g474re_ihm"
SIGNALS = ("i_a", "i_b", "i_c", "vdc")
ADCS = ("ADC1", "ADC2")
#: an internal amplifier's input pin as an analog entry's `adc` (channel 0): OPAMP1_VINP0 .. OPAMP6_VINM0
AMPLIFIER_INPUT = re.compile(r"OPAMP[1-6]_VIN(P[0-3]|M0)")
ENCODER_TIMERS = ("TIM3", "TIM4")
#: a GPIO pin as a board file names it: port letter A-G and pin 0-15 ("PB6")
PIN = re.compile(r"P([A-G])(1[0-5]|[0-9])")
#: hall placements: the electrical angle between sensors A, B and C [degrees]
HALL_SPACINGS = (120, 60)


@dataclass(frozen=True, slots=True)
class AnalogInput:
    """One ADC input: volts = offset_v + gain · signal, plus noise_v rms."""

    signal: str
    adc: str
    channel: int
    offset_v: float
    gain: float
    noise_v: float


@dataclass(frozen=True, slots=True)
class HallInputs:
    """Three hall sensors on GPIO inputs: `pins` [(port letter, pin)] carry A, B, C; sensor k reads high while the
    electrical angle minus `offset_rad` minus k · `spacing_deg` lies in [0, π) (modulo 2π)."""

    pins: tuple[tuple[str, int], tuple[str, int], tuple[str, int]]
    spacing_deg: int
    offset_rad: float
    #: the general-purpose timer whose CH1-CH3 the sensors also feed (its hall interface, CR2.TI1S), or None
    timer: str | None = None


@dataclass(frozen=True, slots=True)
class BoardDescription:
    name: str
    description: str
    part: Part
    hse_hz: int
    vref_v: float
    pwm_timer: str
    pwm_channels: tuple[int, ...]
    analog: tuple[AnalogInput, ...]
    encoder_timer: str | None
    encoder_lines: int
    #: the board's overcurrent protection on TIM1's BKIN pin: the phase current magnitude that trips it [A] (None:
    #: BKIN not wired) and the pin's level then (low for an open-drain fault output)
    break_overcurrent_a: float | None = None
    break_active_low: bool = True
    hall: HallInputs | None = None


def board_names() -> list[str]:
    """The bundled boards."""
    return sorted(p.stem for p in BOARDS_DIR.glob("*.toml"))


def _field(table: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str) -> Any:
    if key not in table:
        raise BoardError(f"{where}: missing '{key}'")
    value = table[key]
    if not isinstance(value, kind) or isinstance(value, bool):
        raise BoardError(f"{where}: '{key}' = {value!r} has the wrong type")
    return value


def load_board(spec: str | Path | None = None) -> BoardDescription:
    """The board `spec`: a bundled name (`board_names()`), a TOML file, or None for the default."""
    text = str(spec) if spec is not None else DEFAULT_BOARD
    path = Path(text).expanduser()
    if not path.suffix and not path.exists():
        path = BOARDS_DIR / f"{text}.toml"
        if not path.is_file():
            raise BoardError(f"--board {text!r}: no such board (bundled: {', '.join(board_names())}; or a TOML file)")
    where = f"board file {path}"
    try:
        raw = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise BoardError(f"{where}: {exc}") from None
    part = part_named(_field(raw, "part", str, where))
    hse = _field(raw, "hse_hz", int, where)
    if not 4_000_000 <= hse <= 48_000_000:
        raise BoardError(f"{where}: 'hse_hz' = {hse} outside the HSE's 4-48 MHz")
    vref = float(_field(raw, "vref_v", (int, float), where))
    if not 1.62 <= vref <= 3.6:
        raise BoardError(f"{where}: 'vref_v' = {vref} outside 1.62-3.6 V")
    pwm = _field(raw, "pwm", dict, where)
    timer = _field(pwm, "timer", str, f"{where} [pwm]")
    if timer != "TIM1":
        raise BoardError(f"{where} [pwm]: 'timer' = {timer!r}: only TIM1 is modelled")
    channels = _field(pwm, "channels", list, f"{where} [pwm]")
    if len(channels) != 3 or any(not isinstance(c, int) or not 1 <= c <= 4 for c in channels):
        raise BoardError(f"{where} [pwm]: 'channels' = {channels!r}: three channels 1-4 (phases a, b, c)")
    inputs = []
    for i, entry in enumerate(_field(raw, "analog", list, where)):
        at = f"{where} [[analog]] #{i + 1}"
        signal = _field(entry, "signal", str, at)
        if signal not in SIGNALS:
            raise BoardError(f"{at}: 'signal' = {signal!r} (one of {', '.join(SIGNALS)})")
        adc = _field(entry, "adc", str, at)
        amplifier = AMPLIFIER_INPUT.fullmatch(adc) is not None
        if adc not in ADCS and not amplifier:
            raise BoardError(f"{at}: 'adc' = {adc!r} (one of {', '.join(ADCS)}) or an amplifier input "
                             "OPAMPn_VINPk / OPAMPn_VINM0")
        channel = _field(entry, "channel", int, at) if not amplifier else int(entry.get("channel", 0))
        if amplifier and channel != 0:
            raise BoardError(f"{at}: 'channel' = {channel}: an amplifier input {adc} has no channel (0 or none)")
        if not amplifier and not 1 <= channel <= 18:
            raise BoardError(f"{at}: 'channel' = {channel} outside 1-18")
        noise = float(entry.get("noise_v", 0.0))
        if noise < 0:
            raise BoardError(f"{at}: 'noise_v' = {noise} is negative")
        inputs.append(AnalogInput(signal, adc, channel, float(_field(entry, "offset_v", (int, float), at)),
                                  float(_field(entry, "gain", (int, float), at)), noise))
    encoder = raw.get("encoder")
    enc_timer, lines = None, 0
    if encoder is not None:
        enc_timer = _field(encoder, "timer", str, f"{where} [encoder]")
        if enc_timer not in ENCODER_TIMERS:
            raise BoardError(f"{where} [encoder]: 'timer' = {enc_timer!r} (one of {', '.join(ENCODER_TIMERS)})")
        lines = _field(encoder, "lines", int, f"{where} [encoder]")
        if not 1 <= lines <= 1 << 20:
            raise BoardError(f"{where} [encoder]: 'lines' = {lines} outside 1-1048576")
    hall = _hall(raw["hall"], f"{where} [hall]") if "hall" in raw else None
    return BoardDescription(path.stem, str(raw.get("description", "")), part, hse, vref, timer,
                            tuple(c - 1 for c in channels), tuple(inputs), enc_timer, lines,
                            *_break_input(raw.get("break_input"), f"{where} [break_input]"), hall)


def _break_input(table: Any, where: str) -> tuple[float | None, bool]:
    """[break_input]: overcurrent_a (> 0) and active_low (default true); (None, True) without the table."""
    if table is None:
        return None, True
    if not isinstance(table, dict):
        raise BoardError(f"{where}: a table (overcurrent_a, active_low)")
    level = float(_field(table, "overcurrent_a", (int, float), where))
    if not 0.0 < level < 1e6:
        raise BoardError(f"{where}: 'overcurrent_a' = {level} outside (0, 1e6) A")
    active_low = table.get("active_low", True)
    if not isinstance(active_low, bool):
        raise BoardError(f"{where}: 'active_low' = {active_low!r} is not true or false")
    return level, active_low


def _hall(table: Any, where: str) -> HallInputs:
    """The `[hall]` table: pins = ["PB6", "PB7", "PB8"] (A, B, C), spacing_deg = 120 or 60, offset_rad, and
    optionally timer = "TIM3" or "TIM4" (the timer whose CH1-CH3 they feed)."""
    if not isinstance(table, dict):
        raise BoardError(f"{where}: must be a table (pins, spacing_deg, offset_rad)")
    names = _field(table, "pins", list, where)
    pins: list[tuple[str, int]] = []
    for name in names:
        match = PIN.fullmatch(name) if isinstance(name, str) else None
        if match is None:
            raise BoardError(f"{where}: 'pins' = {names!r}: each a GPIO pin PA0-PG15 (\"PB6\")")
        pins.append((match.group(1), int(match.group(2))))
    if len(pins) != 3:
        raise BoardError(f"{where}: 'pins' = {names!r}: three pins (hall A, B, C)")
    if len(set(pins)) != 3:
        raise BoardError(f"{where}: 'pins' = {names!r}: the three pins must differ")
    if len({pin for _, pin in pins}) != 3:
        raise BoardError(f"{where}: 'pins' = {names!r}: pins of the same number share one EXTI line; use "
                         "three different pin numbers")
    spacing = table.get("spacing_deg", 120)
    if isinstance(spacing, bool) or spacing not in HALL_SPACINGS:
        raise BoardError(f"{where}: 'spacing_deg' = {spacing!r} (120 or 60 electrical degrees between sensors)")
    offset = table.get("offset_rad", 0.0)
    if isinstance(offset, bool) or not isinstance(offset, (int, float)) or not math.isfinite(offset):
        raise BoardError(f"{where}: 'offset_rad' = {offset!r}: a finite electrical angle [rad]")
    timer = table.get("timer")
    if timer is not None and timer not in ENCODER_TIMERS:
        raise BoardError(f"{where}: 'timer' = {timer!r} (one of {', '.join(ENCODER_TIMERS)}: the timer whose CH1-CH3 "
                         "the sensors feed)")
    unknown = sorted(set(table) - {"pins", "spacing_deg", "offset_rad", "timer"})
    if unknown:
        raise BoardError(f"{where}: unknown field '{unknown[0]}' (pins, spacing_deg, offset_rad, timer)")
    return HallInputs((pins[0], pins[1], pins[2]), int(spacing), float(offset), timer)
