"""Link fault injection (src/pmsm_hil/protocol/links/faults.py): spec parsing, determinism, rates, what each fault class
does on a python-can virtual link pair, and what the decoder makes of corrupted frames."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import pytest

from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.errors import LinkSpecError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import BusLink, Link
from pmsm_hil.protocol.links.faults import (
    COUNT_KEYS,
    DirectionFaults,
    FaultEvent,
    FaultSpec,
    FaultyLink,
    parse_fault_spec,
)
from pmsm_hil.protocol.messages import Command

Opener = Callable[..., BusLink]
CHANNEL = "virtual:faults-test"
N = 10_000
DT = 1e-4  # run time between frames [s]


class Clock:
    """Run time [s] set by the test."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def frame(i: int, arbitration_id: int = 0x108) -> Frame:
    return Frame(arbitration_id, i.to_bytes(4, "little") + b"\xa5\x5a\x00\xff", False)


def index(fr: Frame) -> int:
    return int.from_bytes(fr.data[:4], "little")


def drain(link: Link) -> list[Frame]:
    out = []
    while (fr := link.poll()) is not None:
        out.append(fr)
    return out


@pytest.fixture
def pair(links: Opener) -> tuple[BusLink, BusLink]:
    return links(CHANNEL, "host"), links(CHANNEL, "target")


def exchange(pair: tuple[BusLink, BusLink], spec: FaultSpec | str, n: int = N,
             ) -> tuple[list[Frame], list[Frame], FaultyLink, list[FaultEvent]]:
    """n frames each way, one per DT of run time; returns (received by target, received by host, link, events)."""
    host, target = pair
    clock = Clock()
    fl = FaultyLink(host, parse_fault_spec(spec) if isinstance(spec, str) else spec, clock)
    up: list[Frame] = []
    down: list[Frame] = []
    for i in range(n):
        clock.t = i * DT
        fl.send([frame(i, 0x108)])
        up += drain(target)
        target.send([frame(i, 0x118)])
        down += drain(fl)
    clock.t = math.inf  # release everything still delayed
    fl.pump()
    up += drain(target)
    down += drain(fl)
    return up, down, fl, fl.take_events()


# ---------------------------------------------------------------- parsing

def test_parse_full_spec() -> None:
    s = parse_fault_spec("drop=0.1, dup=0.02,corrupt=1e-3,delay=200us,jitter=0.5ms,reorder=0.05,"
                         "silence=0.1:250ms,seed=7")
    both = DirectionFaults(drop=0.1, dup=0.02, corrupt=1e-3, reorder=0.05, delay_s=200e-6, jitter_s=0.5e-3,
                           silence=(0.1, 0.25))
    assert s.up == both and s.down == both and s.seed == 7 and s.active
    assert parse_fault_spec(str(s)) == s


def test_parse_directional_overrides_plain_in_any_order() -> None:
    s = parse_fault_spec("drop.down=0,drop=0.3,delay.up=2ms,silence.down=1:2")
    assert (s.up.drop, s.down.drop) == (0.3, 0.0)
    assert (s.up.delay_s, s.down.delay_s) == (0.002, 0.0)
    assert (s.up.silence, s.down.silence) == (None, (1.0, 2.0))
    assert s.seed == 0
    assert parse_fault_spec(str(s)) == s
    assert s.direction("up") is s.up and s.direction("down") is s.down


@pytest.mark.parametrize(("text", "seconds"), [("1", 1.0), ("0.5s", 0.5), ("2ms", 2e-3), ("200us", 200e-6),
                                               ("200µs", 200e-6), ("1500ns", 1.5e-6), ("1e-3", 1e-3), ("0", 0.0)])
def test_parse_durations(text: str, seconds: float) -> None:
    assert parse_fault_spec(f"delay={text}").up.delay_s == pytest.approx(seconds, rel=1e-12)


def test_inactive_specs() -> None:
    for text in ("", "  ", "seed=3", "drop=0,dup=0,corrupt=0,reorder=0,delay=0,jitter=0", "silence=1:1"):
        assert not parse_fault_spec(text).active, text
    assert FaultSpec() == parse_fault_spec("")
    assert parse_fault_spec("reorder.down=0.1").active and not parse_fault_spec("reorder.down=0.1").up.active


@pytest.mark.parametrize(("text", "named"), [
    ("lose=0.1", "lose"),
    ("drop.sideways=0.1", "drop.sideways"),
    ("seed.up=3", "seed.up"),
    ("drop=1.5", "drop=1.5"),
    ("dup.down=-0.1", "dup.down=-0.1"),
    ("corrupt=lots", "corrupt=lots"),
    ("reorder=nan", "reorder=nan"),
    ("delay=-1ms", "delay=-1ms"),
    ("jitter=fast", "jitter=fast"),
    ("delay=3 parsecs", "delay=3 parsecs"),
    ("delay=inf", "delay=inf"),
    ("silence=2:1", "silence=2:1"),
    ("silence=1", "silence=1"),
    ("silence=a:b", "silence=a:b"),
    ("silence.up=-1:1", "silence.up=-1:1"),
    ("seed=1.5", "seed=1.5"),
    ("drop", "'drop'"),
    ("drop=0.1,,dup=0.1", "''"),
    ("=0.1", "'=0.1'"),
    ("drop=0.1,drop=0.2", "drop=0.2"),
])
def test_parse_errors_name_the_item(text: str, named: str) -> None:
    with pytest.raises(LinkSpecError) as err:
        parse_fault_spec(text)
    msg = str(err.value)
    assert named in msg and "\n" not in msg


def test_direction_faults_validated_at_construction() -> None:
    with pytest.raises(LinkSpecError, match="drop"):
        DirectionFaults(drop=2.0)
    with pytest.raises(LinkSpecError, match="T1 < T0"):
        DirectionFaults(silence=(2.0, 1.0))


# ---------------------------------------------------------------- determinism and rates

SPEC_ALL = "drop=0.05,dup=0.05,corrupt=0.05,reorder=0.05,delay=150us,jitter=300us,silence=0.3:0.35,seed=11"


def test_same_seed_same_faults(pair: tuple[BusLink, BusLink]) -> None:
    a = exchange(pair, SPEC_ALL)
    b = exchange(pair, SPEC_ALL)
    assert a[0] == b[0] and a[1] == b[1] and a[3] == b[3]
    assert a[2].counts == b[2].counts and a[2].counts_by_direction == b[2].counts_by_direction
    assert all(a[2].counts[k] > 0 for k in COUNT_KEYS)
    assert sum(a[2].counts.values()) == len(a[3])  # every counted fault logged once
    c = exchange(pair, SPEC_ALL.replace("seed=11", "seed=12"))
    assert c[0] != a[0] and c[1] != a[1]
    assert a[0] != a[1][: len(a[0])]  # the directions draw from different generators


def test_fault_classes_do_not_shift_each_other(pair: tuple[BusLink, BusLink]) -> None:
    def drops(spec: str) -> list[tuple[float, str]]:
        _, _, _, events = exchange(pair, spec, n=2000)
        return [(e.t_s, e.direction) for e in events if e.kind == "drop"]

    alone = drops("drop=0.1,seed=3")
    assert len(alone) > 300 and alone == drops("drop=0.1,dup=0.3,corrupt=0.2,reorder=0.2,seed=3")


@pytest.mark.parametrize("key", ["drop", "dup", "corrupt"])
def test_rates_within_four_sigma(pair: tuple[BusLink, BusLink], key: str) -> None:
    p = 0.1
    up, down, fl, _ = exchange(pair, f"{key}={p},seed=5")
    counter = {"drop": "dropped", "dup": "duplicated", "corrupt": "corrupted"}[key]
    bound = 4 * math.sqrt(N * p * (1 - p))
    for direction, got in (("up", up), ("down", down)):
        k = fl.counts_by_direction[direction][counter]
        assert abs(k - N * p) < bound, (direction, k)
        if key == "drop":
            assert len(got) == N - k
        elif key == "dup":
            assert len(got) == N + k
        else:
            sent = [frame(i, got[0].arbitration_id) for i in range(N)]
            assert sum(a != b for a, b in zip(got, sent, strict=True)) == k
    assert fl.counts[counter] == sum(fl.counts_by_direction[d][counter] for d in ("up", "down"))


def test_reorder_rate(pair: tuple[BusLink, BusLink]) -> None:
    p = 0.1
    _, _, fl, _ = exchange(pair, f"reorder={p},seed=5")
    expected = N * p / (1 + p)  # a frame that is a swap partner is not swapped again
    for direction in ("up", "down"):
        assert abs(fl.counts_by_direction[direction]["reordered"] - expected) < 4 * math.sqrt(expected)


# ---------------------------------------------------------------- each fault class

def test_inactive_wrapper_passes_everything(pair: tuple[BusLink, BusLink]) -> None:
    up, down, fl, events = exchange(pair, FaultSpec(), n=100)
    assert isinstance(fl, Link) and fl.stats is pair[0].stats and fl.fd == pair[0].fd
    assert up == [frame(i, 0x108) for i in range(100)] and down == [frame(i, 0x118) for i in range(100)]
    assert fl.counts == dict.fromkeys(COUNT_KEYS, 0) and events == []


def test_drop_one_direction_only(pair: tuple[BusLink, BusLink]) -> None:
    up, down, fl, events = exchange(pair, "drop=1,drop.down=0", n=50)
    assert up == [] and down == [frame(i, 0x118) for i in range(50)]
    assert fl.counts["dropped"] == 50 and fl.counts_by_direction["down"]["dropped"] == 0
    assert events[0] == FaultEvent(0.0, "up", "drop", 0x108)


def test_dup_delivers_twice(pair: tuple[BusLink, BusLink]) -> None:
    up, down, fl, _ = exchange(pair, "dup=1", n=20)
    assert up == [frame(i // 2, 0x108) for i in range(40)]
    assert down == [frame(i // 2, 0x118) for i in range(40)]
    assert fl.counts["duplicated"] == 40


def test_reorder_swaps_with_next(pair: tuple[BusLink, BusLink]) -> None:
    up, down, fl, _ = exchange(pair, "reorder=1", n=10)
    order = [1, 0, 3, 2, 5, 4, 7, 6, 9, 8]
    assert [index(f) for f in up] == order and [index(f) for f in down] == order
    assert fl.counts_by_direction["up"]["reordered"] == 5
    # inside one send call too
    host, target = pair
    fl2 = FaultyLink(host, parse_fault_spec("reorder.up=1"), Clock())
    fl2.send([frame(0), frame(1), frame(2)])
    assert [index(f) for f in drain(target)] == [1, 0]
    assert fl2.pending == 1  # frame 2 waits for a partner
    fl2.send([frame(3)])
    assert [index(f) for f in drain(target)] == [3, 2]


def test_delay_holds_until_the_run_clock_passes(pair: tuple[BusLink, BusLink]) -> None:
    host, target = pair
    clock = Clock()
    fl = FaultyLink(host, parse_fault_spec("delay=1ms"), clock)
    fl.send([frame(0)])
    assert target.poll() is None and fl.pending == 1 and fl.next_release_s() == pytest.approx(1e-3)
    clock.t = 0.9e-3
    assert fl.poll() is None and target.poll() is None
    clock.t = 1e-3
    assert fl.poll() is None and target.poll() == frame(0)  # released by the host's poll
    # down: held from the poll that reads it
    clock.t = 0.01
    target.send([frame(1, 0x118)])
    assert fl.recv(0.01) is None and fl.pending == 1
    clock.t = 0.011
    assert fl.poll() == frame(1, 0x118)
    assert fl.counts["delayed"] == 2 and fl.pending == 0
    assert [(e.t_s, e.direction, e.kind) for e in fl.take_events()] == [(0.0, "up", "delay"), (0.01, "down", "delay")]


def test_jitter_keeps_order_and_bounds(pair: tuple[BusLink, BusLink]) -> None:
    host, target = pair
    clock = Clock()
    fl = FaultyLink(host, parse_fault_spec("delay.up=1ms,jitter.up=1ms,seed=2"), clock)
    arrival: dict[int, float] = {}
    step = 1e-5
    for k in range(2000):
        clock.t = k * step
        if k % 10 == 0 and k < 1000:
            fl.send([frame(k // 10)])
        fl.pump()
        for fr in drain(target):
            arrival[index(fr)] = clock.t
    assert list(arrival) == list(range(100))  # all arrived, in order
    lags = [arrival[i] - i * 10 * step for i in range(100)]
    assert min(lags) >= 1e-3 - 1e-12 and max(lags) <= 2e-3 + step
    assert max(lags) - min(lags) > 0.5e-3


def test_silence_drops_both_directions(pair: tuple[BusLink, BusLink]) -> None:
    spec = parse_fault_spec("silence=0.1:0.2")
    host, target = pair
    clock = Clock()
    fl = FaultyLink(host, spec, clock)
    up: list[int] = []
    down: list[int] = []
    for i in range(30):
        clock.t = i * 0.01
        fl.send([frame(i)])
        up += [index(f) for f in drain(target)]
        target.send([frame(i, 0x118)])
        down += [index(f) for f in drain(fl)]
    kept = [i for i in range(30) if not 10 <= i < 20]
    assert up == kept and down == kept
    assert fl.counts_by_direction["up"]["dropped"] == 10 == fl.counts_by_direction["down"]["dropped"]
    assert {e.kind for e in fl.take_events()} == {"silence"}


def test_corrupt_flips_exactly_one_bit(pair: tuple[BusLink, BusLink]) -> None:
    up, down, fl, events = exchange(pair, "corrupt=1,seed=4", n=2000)
    bits: set[int] = set()
    for got, aid in ((up, 0x108), (down, 0x118)):
        assert len(got) == 2000
        for i, fr in enumerate(got):
            ref = frame(i, aid)
            assert fr.arbitration_id == aid and len(fr.data) == len(ref.data) and fr.is_fd == ref.is_fd
            x = int.from_bytes(fr.data, "little") ^ int.from_bytes(ref.data, "little")
            assert x.bit_count() == 1
            bits.add(x.bit_length() - 1)
    assert bits == set(range(64))  # every bit position gets hit
    assert fl.counts["corrupted"] == 4000 == len(events)


def test_event_ring_is_bounded_and_drained(pair: tuple[BusLink, BusLink]) -> None:
    host, _ = pair
    clock = Clock()
    fl = FaultyLink(host, parse_fault_spec("drop.up=1"), clock, event_capacity=8)
    for i in range(20):
        clock.t = i * DT
        fl.send([frame(i)])
    ev = fl.take_events()
    assert len(ev) == 8 and fl.events_lost == 12
    assert ev[-1] == FaultEvent(19 * DT, "up", "drop", 0x108)
    assert fl.take_events() == []
    fl.send([frame(20)])
    assert len(fl.take_events()) == 1 and fl.counts["dropped"] == 21
    with pytest.raises(ValueError, match="event_capacity"):
        FaultyLink(host, FaultSpec(), clock, event_capacity=0)


def test_close_closes_the_wrapped_link(pair: tuple[BusLink, BusLink]) -> None:
    host, _ = pair
    with FaultyLink(host, parse_fault_spec("delay=1"), Clock()) as fl:
        fl.send([frame(0)])
    assert host.bus._is_shutdown and fl.pending == 0


# ---------------------------------------------------------------- corrupted frames and the decoder

TS_NS = 100_000


def command(seq: int) -> Command:
    n = 1 + seq % 3
    durations = (TS_NS,) if n == 1 else (40_000, 60_000) if n == 2 else (20_000, 30_000, 50_000)
    return Command(seq, (4, 6, 2)[:n], durations, 3, 8, 1200 + seq, 0)


def corrupted(pair: tuple[BusLink, BusLink], spec: str, profile: str = "canfd", n: int = 3000,
              ) -> Iterator[tuple[Command, list[Frame]]]:
    """Commands seq 1..n sent by the target; yields each with the frames the faulty host end delivers."""
    host, target = pair
    codec = FrameCodec(profile)  # type: ignore[arg-type]
    fl = FaultyLink(host, parse_fault_spec(spec), Clock())
    for seq in range(1, n + 1):
        sent = command(seq)
        target.send(codec.encode(sent))
        yield sent, drain(fl)


def test_corrupted_command_stream_is_counted_never_raises(pair: tuple[BusLink, BusLink]) -> None:
    """Every frame of a stream of corrupted Commands is either delivered or counted as rejected."""
    dec = FrameCodec("canfd").decoder()
    for _, frames in corrupted(pair, "corrupt.down=1,seed=9"):
        assert len(frames) == 1
        dec.feed(frames[0])
    s = dec.stats
    rejected = s.unknown_id + s.bad_length + s.bad_value + s.stale + s.duplicate + s.mixed_seq
    assert s.frames == 3000 and s.messages + rejected == 3000
    assert s.bad_value > 0 and s.stale > 0  # n_states flipped to 0; genuine seqs behind a flipped one


def test_single_bit_flips_mostly_pass_the_decoder(pair: tuple[BusLink, BusLink]) -> None:
    """The decoder has no integrity check of its own: it rejects only impossible values (n_states 0) and
    out-of-sequence seqs, so most single bit flips come through as a different Command (docs/runner.md,
    "Link fault injection": the runner's contract checks and a link check have to catch them)."""
    codec = FrameCodec("canfd")
    rejected = changed = 0
    for sent, frames in corrupted(pair, "corrupt.down=1,seed=9"):
        dec = codec.decoder()  # a decoder that has just delivered seq - 1
        assert dec.feed(codec.encode(command(sent.seq - 1))[0]) is not None
        got = dec.feed(frames[0])
        rejected += got is None
        changed += got is not None and got != sent
    # exhaustive over the 160 bits of CmdFd (n_states 1..3): 2.3 % rejected, 77 % changed, 21 % ignored bits
    assert rejected < 0.05 * 3000 and changed > 0.7 * 3000


def test_corrupted_classic_frames_never_raise(pair: tuple[BusLink, BusLink]) -> None:
    dec = FrameCodec("can").decoder()
    for _, frames in corrupted(pair, "corrupt.down=0.5,seed=9", "can", 1000):
        assert len(frames) == 3
        for fr in frames:
            dec.feed(fr)
    assert dec.stats.frames == 3000 and dec.stats.bad_value > 0
