"""Link fault injection, host side: `FaultyLink(link, spec, clock)` wraps any `Link` and drops, duplicates,
corrupts, delays, reorders or silences the frames going up (host → target, `send`) and down
(target → host, `poll` / `recv`), deterministically from a seed.

Spec syntax (`parse_fault_spec`, the text of `hil run --fault`): comma-separated `KEY=VALUE` items,

    drop=P  dup=P  corrupt=P  reorder=P   probability per frame, 0 ≤ P ≤ 1
    delay=D  jitter=D                     duration ≥ 0: seconds, or with a suffix s / ms / us (µs) / ns
    silence=T0:T1                         run-time window [T0, T1) in which every frame is dropped
    seed=S                                integer (default 0)

Every key but `seed` also exists per direction: `KEY.up` (host → target) and `KEY.down` (target → host);
a plain key sets both directions and a directional key overrides it whatever the order
(`drop=0.1,drop.down=0` drops only measurements). A key given twice, an unknown key, a probability outside
[0, 1], a negative or non-numeric duration, T1 < T0 or a non-integer seed raise `LinkSpecError` naming the
item. `str(spec)` gives the canonical text, which parses back to an equal spec.

What each fault does to one frame, in this order (each direction has its own `random.Random`, seeded from
`seed` and the direction, and draws exactly five numbers per frame entering the wrapper, whatever happens
to it — so the faults of one class do not move when another class is switched on):
    silence  run time in [T0, T1) at entry: discarded (counted as `dropped`, logged as `silence`)
    drop     discarded
    corrupt  one uniformly drawn bit of the payload flipped (same id, same length)
    dup      sent / delivered twice, back to back
    delay    held until run time ≥ entry time + delay + U[0, jitter); frames stay in order (a frame never
             overtakes an earlier one: reordering is the `reorder` fault's job)
    reorder  held and sent / delivered right after the next frame of the same direction (a swap; the partner
             of a swap is not swapped again). With one frame per message each way (CAN FD, serial, UDP) this
             holds a message back by one exchange.

Run time, not wall time: `clock()` returns the runner's run time in seconds (the virtual time in lockstep).
Held frames are released by the first `send` / `poll` / `recv` / `pump` call that finds clock() ≥ their
release time; in lockstep the clock stands still while the runner waits, so a delayed frame comes out on a
poll after the runner has advanced time (a delay the runner does not wait out is a missing frame).

Who detects a corrupted frame: the wrapper sits above the transport, so an injected bit flip is never
seen by a link CRC — going up the transport computes its CRC over the corrupted payload, coming down the
CRC was checked before. It models corruption that got past the link (or a link without a check: the
virtual bus, UDP between hosts without checksums). On the wire itself CAN / CAN FD frames are protected by
the controller's CRC (a bad frame is retransmitted: a delay, never corruption) and serial packets by
CRC-16/CCITT (`LinkStats.crc_errors`, the packet is dropped). What reaches the codec is checked only by the
`FrameDecoder`: unknown id, length, impossible values (n_states 0) and sequence numbers (stale, duplicate,
mixed) — most single bit flips in a Command pass it (see docs/runner.md, "Link fault injection").

Counters: `counts` (exactly `dropped`, `duplicated`, `corrupted`, `delayed`, `reordered`, both directions)
and `counts_by_direction["up" | "down"]` (the same keys). Events: a bounded ring of `FaultEvent(t_s,
direction, kind, arbitration_id)`; `take_events()` returns those since the last call; overwritten ones are
counted in `events_lost`.
"""

from __future__ import annotations

import math
import random
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from decimal import Decimal, InvalidOperation
from typing import Literal, NamedTuple

from pmsm_hil.protocol.errors import LinkSpecError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links.link import Link
from pmsm_hil.protocol.links.stats import LinkStats

Direction = Literal["up", "down"]
DIRECTIONS: tuple[Direction, ...] = ("up", "down")
#: The keys of `FaultyLink.counts` (metrics `link_faults`).
COUNT_KEYS: tuple[str, ...] = ("dropped", "duplicated", "corrupted", "delayed", "reordered")
#: Event kind -> the counter it increments.
EVENT_COUNTER: dict[str, str] = {"silence": "dropped", "drop": "dropped", "corrupt": "corrupted",
                                 "dup": "duplicated", "delay": "delayed", "reorder": "reordered"}
DEFAULT_EVENT_CAPACITY = 32768

_PROBABILITY_KEYS = ("drop", "dup", "corrupt", "reorder")
_DURATION_KEYS = {"delay": "delay_s", "jitter": "jitter_s"}
_KEYS = (*_PROBABILITY_KEYS, *_DURATION_KEYS, "silence")
_UNITS = (("ms", Decimal("1e-3")), ("us", Decimal("1e-6")), ("µs", Decimal("1e-6")), ("ns", Decimal("1e-9")),
          ("s", Decimal(1)))


class FaultEvent(NamedTuple):
    """One injected fault: run time [s], direction, kind (`EVENT_COUNTER` keys), frame id."""

    t_s: float
    direction: str
    kind: str
    arbitration_id: int


def _bad(key: str, value: object, reason: str) -> LinkSpecError:
    return LinkSpecError(f"fault {key}={value}: {reason}")


def _check_probability(key: str, p: float) -> None:
    if not 0.0 <= p <= 1.0:  # False for NaN too
        raise _bad(key, p, "probability outside [0, 1]")


def _check_duration(key: str, d: float) -> None:
    if not (math.isfinite(d) and d >= 0.0):
        raise _bad(key, d, "duration must be finite and ≥ 0")


@dataclass(frozen=True, slots=True)
class DirectionFaults:
    """Faults of one direction: probabilities per frame, delay and jitter [s], silence window [T0, T1) [s]."""

    drop: float = 0.0
    dup: float = 0.0
    corrupt: float = 0.0
    reorder: float = 0.0
    delay_s: float = 0.0
    jitter_s: float = 0.0
    silence: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        for key in _PROBABILITY_KEYS:
            _check_probability(key, getattr(self, key))
        for key, name in _DURATION_KEYS.items():
            _check_duration(key, getattr(self, name))
        if self.silence is not None:
            t0, t1 = self.silence
            _check_duration("silence", t0)
            _check_duration("silence", t1)
            if t1 < t0:
                raise _bad("silence", f"{t0}:{t1}", "T1 < T0")

    @property
    def active(self) -> bool:
        """True if any fault can hit a frame of this direction."""
        sil = self.silence
        return bool(self.drop or self.dup or self.corrupt or self.reorder or self.delay_s or self.jitter_s
                    or (sil is not None and sil[1] > sil[0]))


@dataclass(frozen=True, slots=True)
class FaultSpec:
    """Faults of both directions (up = host → target, down = target → host) and the seed."""

    up: DirectionFaults = field(default_factory=DirectionFaults)
    down: DirectionFaults = field(default_factory=DirectionFaults)
    seed: int = 0

    @property
    def active(self) -> bool:
        """False when no fault can happen: the runner then does not wrap its link at all."""
        return self.up.active or self.down.active

    @property
    def delays(self) -> bool:
        """True when frames can be held for a time (delay or jitter in a direction)."""
        return any(d.delay_s > 0.0 or d.jitter_s > 0.0 for d in (self.up, self.down))

    def direction(self, direction: Direction) -> DirectionFaults:
        """The faults of `direction` ("up" or "down")."""
        return self.up if direction == "up" else self.down

    def __str__(self) -> str:
        """Canonical spec text (parses back to an equal spec)."""
        items: list[str] = []
        for f in fields(DirectionFaults):
            key = f.name.removesuffix("_s")
            a, b = getattr(self.up, f.name), getattr(self.down, f.name)
            for suffix, v in ((("", a),) if a == b else ((".up", a), (".down", b))):
                if v:
                    items.append(f"{key}{suffix}={v[0]!r}:{v[1]!r}" if key == "silence" else f"{key}{suffix}={v!r}")
        items.append(f"seed={self.seed}")
        return ",".join(items)


def _parse_duration(key: str, text: str, shown: str | None = None) -> float:
    """Seconds from "D[s|ms|us|µs|ns]" (exact decimal scaling: "200us" == 0.0002); errors show `shown`."""
    num, scale = text.strip(), Decimal(1)
    for suffix, s in _UNITS:
        if num.endswith(suffix):
            num, scale = num[: -len(suffix)].strip(), s
            break
    try:
        value = float(Decimal(num) * scale)
    except (InvalidOperation, ValueError):  # ValueError: sNaN
        raise _bad(key, shown or text, "not a duration (seconds, or with a suffix ms, us, ns)") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise _bad(key, shown or text, "duration must be finite and ≥ 0")
    return value


def _parse_value(base: str, key: str, text: str) -> float | tuple[float, float]:
    if base in _DURATION_KEYS:
        return _parse_duration(key, text)
    if base == "silence":
        parts = text.split(":")
        if len(parts) != 2:
            raise _bad(key, text, "expected T0:T1 (run time, s)")
        t0, t1 = (_parse_duration(key, p, text) for p in parts)
        if t1 < t0:
            raise _bad(key, text, "T1 < T0")
        return (t0, t1)
    try:
        p = float(text)
    except ValueError:
        raise _bad(key, text, "not a probability") from None
    _check_probability(key, p)
    return p


def parse_fault_spec(text: str) -> FaultSpec:
    """Parse the `--fault` text (module docstring); raises LinkSpecError naming the bad item in one line."""
    plain: dict[str, float | tuple[float, float]] = {}
    per: dict[str, dict[str, float | tuple[float, float]]] = {"up": {}, "down": {}}
    seed = 0
    seen: set[str] = set()
    if not text.strip():
        return FaultSpec()
    for raw in text.split(","):
        item = raw.strip()
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not key:
            raise LinkSpecError(f"fault item {item!r}: expected KEY=VALUE")
        if key in seen:
            raise _bad(key, value, "key given twice")
        seen.add(key)
        if key == "seed":
            try:
                seed = int(value, 10)
            except ValueError:
                raise _bad(key, value, "seed must be an integer") from None
            continue
        base, _, direction = key.partition(".")
        if base not in _KEYS or direction not in ("", "up", "down"):
            raise _bad(key, value, f"unknown key (expected {', '.join(_KEYS)} with optional .up/.down, or seed)")
        (per[direction] if direction else plain)[base] = _parse_value(base, key, value)

    def build(direction: str) -> DirectionFaults:
        v = {**plain, **per[direction]}
        return DirectionFaults(**{_DURATION_KEYS.get(k, k): val for k, val in v.items()})  # type: ignore[arg-type]

    return FaultSpec(build("up"), build("down"), seed)


class _EventRing:
    """Bounded event log; `take` returns and forgets what was added since the last call."""

    __slots__ = ("events", "lost")

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"event_capacity={capacity} must be ≥ 1")
        self.events: deque[FaultEvent] = deque(maxlen=capacity)
        self.lost = 0

    def add(self, ev: FaultEvent) -> None:
        events = self.events
        if len(events) == events.maxlen:
            self.lost += 1
        events.append(ev)

    def take(self) -> list[FaultEvent]:
        """Pop what is there (safe while another thread adds: deque appends and pops are atomic)."""
        out: list[FaultEvent] = []
        pop = self.events.popleft
        while True:
            try:
                out.append(pop())
            except IndexError:
                return out


class _Pipe:
    """The fault pipeline of one direction: faults at entry, a FIFO delay line, then the reorder stage."""

    __slots__ = ("_crc_caught", "_delayed", "_dir", "_f", "_held", "_last_release", "_line", "_mine", "_random",
                 "_ring", "_total")

    def __init__(self, faults: DirectionFaults, seed: int, direction: Direction, total: dict[str, int],
                 mine: dict[str, int], ring: _EventRing, crc_caught: Callable[[], None] | None = None) -> None:
        self._crc_caught = crc_caught
        self._f = faults
        self._random = random.Random(f"pmsm_hil.faults:{seed}:{direction}").random
        self._dir = direction
        self._total = total
        self._mine = mine
        self._ring = ring
        self._delayed = bool(faults.delay_s or faults.jitter_s)
        self._line: deque[tuple[float, Frame, bool]] = deque()  # (release time [s], frame, reorder flag)
        self._held: Frame | None = None  # waiting for its swap partner
        self._last_release = -math.inf

    def _note(self, now: float, kind: str, arbitration_id: int) -> None:
        key = EVENT_COUNTER[kind]
        self._total[key] += 1
        self._mine[key] += 1
        self._ring.add(FaultEvent(now, self._dir, kind, arbitration_id))

    @property
    def pending(self) -> int:
        """Frames held (delay line and reorder stage)."""
        return len(self._line) + (self._held is not None)

    def next_release_s(self) -> float | None:
        """Release time [s] of the oldest frame in the delay line."""
        return self._line[0][0] if self._line else None

    def push(self, fr: Frame, now: float, out: deque[Frame]) -> None:
        """Apply the entry faults to `fr` at run time `now`; frames due for output are appended to `out`."""
        rnd = self._random
        u_drop, u_dup, u_corrupt, u_reorder, u_jitter = rnd(), rnd(), rnd(), rnd(), rnd()
        f = self._f
        sil = f.silence
        if sil is not None and sil[0] <= now < sil[1]:
            self._note(now, "silence", fr[0])
            return
        if u_drop < f.drop:
            self._note(now, "drop", fr[0])
            return
        if u_corrupt < f.corrupt and fr[1]:
            data = bytearray(fr[1])
            nbits = 8 * len(data)
            bit = min(int(u_corrupt / f.corrupt * nbits), nbits - 1)  # u/P is uniform in [0, 1) given u < P
            data[bit >> 3] ^= 1 << (bit & 7)
            fr = Frame(fr[0], bytes(data), fr[2])
            self._note(now, "corrupt", fr[0])
            if self._crc_caught is not None:  # the link's integrity check (CRC) sees it: counted, dropped
                self._crc_caught()
                return
        copies = 1
        if u_dup < f.dup:
            copies = 2
            self._note(now, "dup", fr[0])
        reorder = u_reorder < f.reorder
        if not self._delayed:
            for i in range(copies):
                self._emit(fr, reorder and i == copies - 1, now, out)
            return
        release = max(now + f.delay_s + u_jitter * f.jitter_s, self._last_release)
        self._last_release = release
        if release > now:
            self._note(now, "delay", fr[0])
        line = self._line
        for i in range(copies):
            line.append((release, fr, reorder and i == copies - 1))
        self.release(now, out)

    def release(self, now: float, out: deque[Frame]) -> None:
        """Move the frames of the delay line due at run time `now` through the reorder stage to `out`."""
        line = self._line
        while line and line[0][0] <= now:
            _, fr, reorder = line.popleft()
            self._emit(fr, reorder, now, out)

    def _emit(self, fr: Frame, reorder: bool, now: float, out: deque[Frame]) -> None:
        held = self._held
        if held is not None:
            out.append(fr)
            out.append(held)
            self._held = None
            self._note(now, "reorder", held[0])
        elif reorder:
            self._held = fr
        else:
            out.append(fr)

    def clear(self) -> None:
        self._line.clear()
        self._held = None


class FaultyLink:
    """A `Link` that injects the faults of `spec` into the frames of `link` (module docstring).

    `clock()` returns the run time in seconds; `stats` and `fd` are the wrapped link's. Each direction whose
    faults are all off costs one attribute test per call."""

    stats: LinkStats
    fd: bool

    def __init__(self, link: Link, spec: FaultSpec, clock: Callable[[], float], *,
                 event_capacity: int = DEFAULT_EVENT_CAPACITY, crc_checked: bool = False) -> None:
        """`crc_checked`: the link below has an integrity check (CAN/CAN FD CRC, the serial and UDP CRC-16),
        so a corrupted frame is caught there: counted in `corrupted` and the link's `crc_errors`, and dropped.
        False passes corrupted frames on (what a link without a check would deliver)."""
        self.link = link
        self._crc_checked = crc_checked
        self.spec = spec
        self.clock = clock
        self.stats = link.stats
        self.fd = link.fd
        self.counts: dict[str, int] = dict.fromkeys(COUNT_KEYS, 0)
        self.counts_by_direction: dict[str, dict[str, int]] = {d: dict.fromkeys(COUNT_KEYS, 0) for d in DIRECTIONS}
        self._ring = _EventRing(event_capacity)
        self._up = self._pipe(spec, "up")
        self._down = self._pipe(spec, "down")
        self._up_out: deque[Frame] = deque()
        self._down_out: deque[Frame] = deque()

    def _pipe(self, spec: FaultSpec, direction: Direction) -> _Pipe | None:
        faults = spec.direction(direction)
        if not faults.active:
            return None
        return _Pipe(faults, spec.seed, direction, self.counts, self.counts_by_direction[direction], self._ring,
                     self._count_crc_error if self._crc_checked else None)

    def _count_crc_error(self) -> None:
        self.stats.crc_errors += 1

    # -- Link protocol --
    def send(self, frames: Sequence[Frame]) -> None:
        """Pass `frames` up through the faults; what is due now goes to the wrapped link in one call."""
        up = self._up
        if up is None:
            self.link.send(frames)
            return
        now = self.clock()
        out = self._up_out
        up.release(now, out)
        for fr in frames:
            up.push(fr, now, out)
        self._flush_up()

    def poll(self) -> Frame | None:
        """The next frame coming down through the faults, or None at once (releases due up frames too)."""
        up = self._up
        if up is not None and up.pending:
            up.release(self.clock(), self._up_out)
            self._flush_up()
        down = self._down
        if down is None:
            return self.link.poll()
        out = self._down_out
        if out:
            return out.popleft()
        if down.pending:
            down.release(self.clock(), out)
            if out:
                return out.popleft()
        inner = self.link.poll
        while (fr := inner()) is not None:
            down.push(fr, self.clock(), out)
            if out:
                return out.popleft()
        return None

    def recv(self, timeout_s: float) -> Frame | None:
        """The next frame coming down within `timeout_s` seconds of wall time: busy-polling while frames are held
        (they need the run clock to pass), else waiting in the wrapped link's `recv` (which may block) and passing
        what it gives through the faults."""
        deadline = time.perf_counter() + timeout_s
        while True:
            fr = self.poll()
            left = deadline - time.perf_counter()
            if fr is not None or left <= 0:
                return fr
            up, down = self._up, self._down
            if (up is not None and up.pending) or (down is not None and down.pending):
                continue
            fr = self.link.recv(left)
            if fr is None or down is None:
                return fr
            down.push(fr, self.clock(), self._down_out)
            if self._down_out:
                return self._down_out.popleft()

    def close(self) -> None:
        """Close the wrapped link and forget held frames (idempotent)."""
        for pipe in (self._up, self._down):
            if pipe is not None:
                pipe.clear()
        self._up_out.clear()
        self._down_out.clear()
        self.link.close()

    def __enter__(self) -> FaultyLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- for the runner --
    def pump(self) -> None:
        """Release the frames due at clock() in both directions (up ones are sent; down ones wait for poll)."""
        now = self.clock()
        if self._up is not None:
            self._up.release(now, self._up_out)
            self._flush_up()
        if self._down is not None:
            self._down.release(now, self._down_out)

    @property
    def pending(self) -> int:
        """Frames held in both directions (delay lines, reorder stages, delivered-not-yet-polled)."""
        return sum(p.pending for p in (self._up, self._down) if p is not None) + len(self._down_out)

    def next_release_s(self) -> float | None:
        """Earliest run time [s] at which a delayed frame falls due, or None (reorder holds wait for a frame)."""
        times = [t for p in (self._up, self._down) if p is not None and (t := p.next_release_s()) is not None]
        return min(times) if times else None

    def take_events(self) -> list[FaultEvent]:
        """The events since the last call, oldest first (at most `event_capacity`; see `events_lost`)."""
        return self._ring.take()

    @property
    def events_lost(self) -> int:
        """Events overwritten in the ring before they were taken."""
        return self._ring.lost

    def _flush_up(self) -> None:
        out = self._up_out
        if out:
            batch = list(out)
            out.clear()
            self.link.send(batch)
