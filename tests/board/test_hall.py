"""Hall sensors on GPIO: the pins follow the rotor's electrical angle at the cycle the firmware reads them, EXTI
takes each edge at its instant (SYSCFG EXTICR, RTSR1/FTSR1, IMR1, PR1, the EXTI9_5 line), the edge rate is
6 · p · n / 60 and the sector sequence runs both ways; a bad [hall] field is one line naming it."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from pathlib import Path

import pytest

from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.messages import Measurement
from pmsm_hil.sim_target.stm32g4.board_file import load_board
from pmsm_hil.sim_target.stm32g4.hall import HallSensors
from pmsm_hil.sim_target.stm32g4.link import BoardLink
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.exti import Exti
from pmsm_hil.sim_target.stm32g4.peripherals.gpio import GpioPort
from tests.board.fake_bus import FakeBus

TS = 50e-6
POLE_PAIRS = 4
CODEC = FrameCodec("canfd")
DEFAULT_BOARD = Path(__file__).parents[2] / "src/pmsm_hil/sim_target/stm32g4/boards/nucleo_g474re_ihm.toml"
#: the 120° sector codes C<<2 | B<<1 | A for a rising electrical angle from the offset on
FORWARD = (5, 1, 3, 2, 6, 4)


def board_file(tmp_path: Path, hall: str) -> Path:
    path = tmp_path / "hall_board.toml"
    path.write_text(DEFAULT_BOARD.read_text() + "\n[hall]\n" + hall)
    return path


def run(link: BoardLink, rpm: float, periods: int, theta0: float) -> tuple[float, float]:
    """Measurements at a constant speed: returns the electrical angle at the first and after the last period."""
    omega_m = rpm * 2 * math.pi / 60
    we = POLE_PAIRS * omega_m
    for k in range(periods):
        theta = (theta0 + we * k * TS) % (2 * math.pi)
        link.send(CODEC.encode(Measurement(seq=k & 0xFFFF, i_a=0.0, i_b=0.0, i_c=0.0, theta_e=theta, omega_m=omega_m,
                                           vdc=48.0)))
        while link.poll() is not None:
            pass
    return theta0, theta0 + we * periods * TS


def word(link: BoardLink, name: str) -> int:
    address = link.board.symbol(name)
    assert address is not None, name
    return link.board.cpu.read_u32(address)


def recorded(link: BoardLink, name: str, count: int, size: int) -> list[int]:
    address = link.board.symbol(name)
    assert address is not None, name
    raw = link.board.read_memory(address, count * size)
    return [int.from_bytes(raw[i * size:(i + 1) * size], "little") for i in range(count)]


def crossings(theta_a: float, theta_b: float, offset: float) -> int:
    """Hall edges (multiples of π/3 past the offset) the angle passes from theta_a to theta_b."""
    step = math.pi / 3
    lo, hi = sorted((theta_a - offset, theta_b - offset))
    return math.floor(hi / step) - math.floor(lo / step)


@pytest.mark.parametrize("rpm", [1500.0, -1500.0])
def test_edges_follow_the_rotor_at_6_p_n_over_60_and_the_sectors_run_both_ways(
        build_fw: Callable[..., Path], tmp_path: Path, rpm: float) -> None:
    offset = 0.3
    desc = load_board(board_file(tmp_path, f'pins = ["PB6", "PB7", "PB8"]\nspacing_deg = 120\noffset_rad = {offset}\n'))
    link = BoardLink(build_fw("hall"), desc, ts_s=TS, pole_pairs=POLE_PAIRS)
    periods = 2000  # 0.1 s: 60 edges at 1500 rpm and 4 pole pairs
    theta0 = 0.05
    first, last = run(link, rpm, periods, theta0)
    edges = word(link, "edges")
    # 6 · p · n / 60 edges per second over the run, within one edge
    expected_rate = 6 * POLE_PAIRS * abs(rpm) / 60
    assert abs(edges - expected_rate * periods * TS) <= 1
    # exactly the edges the trajectory passes (the first Measurement moves the angle from 0 to theta0 before the
    # firmware samples: edges from theta0 on)
    assert edges == crossings(first, last, offset) == word(link, "codes_n")
    codes = recorded(link, "codes", edges, 1)
    order = FORWARD if rpm > 0 else tuple(reversed(FORWARD))
    start = order.index(codes[0])
    assert codes == [order[(start + i) % 6] for i in range(edges)]
    # each edge at its instant: the handler's DWT stamps are π/3 of electrical angle apart, within a few cycles
    stamps = recorded(link, "stamps", edges, 4)
    hclk = link.hclk_hz
    sector_cycles = (math.pi / 3) / (POLE_PAIRS * abs(rpm) * 2 * math.pi / 60) * hclk
    gaps = [b - a for a, b in itertools.pairwise(stamps)]
    assert all(abs(g - sector_cycles) < 64 for g in gaps), (sector_cycles, min(gaps), max(gaps))
    assert link.board.isr[16 + 23].entries == edges


def test_idr_reads_the_sector_at_the_instant_of_the_read(build_fw: Callable[..., Path], tmp_path: Path) -> None:
    desc = load_board(board_file(tmp_path, 'pins = ["PB6", "PB7", "PB8"]\n'))
    link = BoardLink(build_fw("hall"), desc, ts_s=TS, pole_pairs=POLE_PAIRS)
    assert word(link, "first_code") == 5  # angle 0 at start-up: A and C high
    halls = link.halls
    assert isinstance(halls, HallSensors)
    gpiob = link.board.peripherals["GPIOB"]
    for sector, code in enumerate(FORWARD):
        link._theta_m = (sector + 0.5) * math.pi / 3 / POLE_PAIRS  # the run side's angle
        assert gpiob.read(0x10, 4, link.board.now) >> 6 & 7 == code == halls.code(link.board.now)


@pytest.mark.parametrize(("hall", "field"), [
    ('pins = ["PB6", "PB7"]\n', "'pins'"),
    ('pins = ["PB6", "PB7", "PH8"]\n', "'pins'"),
    ('pins = ["PB6", "PC6", "PB8"]\n', "'pins'"),
    ('pins = ["PB6", "PB7", "PB8"]\nspacing_deg = 90\n', "'spacing_deg'"),
    ('pins = ["PB6", "PB7", "PB8"]\noffset_rad = "east"\n', "'offset_rad'"),
    ('pins = ["PB6", "PB7", "PB8"]\nofset_rad = 0.1\n', "'ofset_rad'"),
    ('spacing_deg = 120\n', "missing 'pins'"),
])
def test_a_bad_hall_field_is_one_line_naming_it(tmp_path: Path, hall: str, field: str) -> None:
    with pytest.raises(BoardError) as info:
        load_board(board_file(tmp_path, hall))
    text = str(info.value)
    assert "[hall]" in text and field in text and "\n" not in text


class StepDriver:
    """Input pins that change at given cycles: `changes` [(cycle, levels)] in time order."""

    def __init__(self, changes: list[tuple[int, int]]) -> None:
        self.changes = changes

    def levels(self, port: str, now: int) -> int:
        value = 0
        for at, levels in self.changes:
            if at <= now:
                value = levels
        return value

    def next_change(self, port: str, mask: int, now: int) -> int | None:
        current = self.levels(port, now)
        return next((at for at, levels in self.changes if at > now and (levels ^ current) & mask), None)


def test_exti_edges_flags_mask_software_trigger_and_port_selection(bus: FakeBus) -> None:
    for name in ("SYSCFG", "GPIOB", "GPIOC"):
        bus.add(name)
    exti = bus.add_model("EXTI", Exti)
    gpiob = bus.models["GPIOB"]
    assert isinstance(gpiob, GpioPort)
    pin7 = 1 << 7
    gpiob.drive(StepDriver([(100, pin7), (200, 0), (300, pin7)]), pin7)
    syscfg = bus.models["SYSCFG"]
    syscfg.write(0x0C, 4, 1 << 12, 0)              # EXTICR2: EXTI7 on port B
    exti.write(0x08, 4, pin7, 0)                   # RTSR1: rising only, IMR1 still masked
    assert exti.next_event(0) == 100
    exti.advance(100)
    assert exti.read(0x14, 4, 100) == pin7 and bus.pended == []  # PR1 set, no interrupt while masked
    exti.write(0x00, 4, 0xFF82_0000 | pin7, 110)   # IMR1: the pending flag asserts EXTI9_5 now
    assert bus.pended == [23]
    exti.write(0x14, 4, pin7, 120)                 # PR1 write 1 to clear: the line is withdrawn
    assert exti.read(0x14, 4, 120) == 0 and bus.cleared == [23]
    exti.advance(200)                              # a falling edge, not selected
    assert exti.read(0x14, 4, 200) == 0
    assert exti.next_event(200) == 300
    exti.advance(300)
    assert exti.read(0x14, 4, 300) == pin7 and bus.pended == [23, 23] and exti.edges[7] == 2
    exti.write(0x14, 4, pin7, 310)
    exti.write(0x10, 4, 1 << 3, 320)               # SWIER1 sets PR1 (line 3, masked: no interrupt)
    assert exti.read(0x14, 4, 320) == 1 << 3
    syscfg.write(0x0C, 4, 2 << 12, 330)            # EXTI7 to port C (pin low): the switch is no edge
    assert exti.next_event(330) is None and exti.read(0x14, 4, 330) == 1 << 3
    with pytest.raises(BoardError, match=r"SYSCFG EXTICR1: EXTI2 = 9 selects no GPIO port"):
        syscfg.write(0x08, 4, 9 << 8, 340)


@pytest.mark.parametrize(("spacing", "codes"), [(120, FORWARD), (60, (1, 3, 7, 6, 4, 0))])
def test_the_placement_sets_the_sector_codes_and_the_next_edge(spacing: int, codes: tuple[int, ...]) -> None:
    """Sensor k high while θe - offset - k·spacing is in [0, π): six codes per electrical turn, the next edge at the
    next multiple of π/3 (exact to the cycle)."""
    from pmsm_hil.sim_target.stm32g4.board_file import HallInputs

    rate = 1e-4  # [rad per cycle]
    angle = [0.0]
    halls = HallSensors(HallInputs((("B", 6), ("B", 7), ("B", 8)), spacing, 0.2),
                        lambda now: (angle[0] + rate * now, rate))
    start = 0.2 + math.pi / 6  # the middle of the first sector
    seen = []
    for sector in range(6):
        angle[0] = start + sector * math.pi / 3
        seen.append(halls.code(0))
    assert tuple(seen) == codes
    angle[0] = start
    edge = halls.next_change("B", 0x1C0, 0)
    assert edge == math.ceil((math.pi / 6) / rate)  # π/6 to the sector's end
    assert halls.code(edge) != halls.code(edge - 1) and halls.code(edge - 1) == codes[0]


def test_the_timer_hall_interface_captures_the_time_between_edges(build_fw: Callable[..., Path],
                                                                   tmp_path: Path) -> None:
    """TIM4 with CR2.TI1S, reset mode on TI1F_ED and CC1 on TRC: each hall edge captures the 1 MHz count since the
    previous one into CCR1 (a sector's time at 1500 rpm and 4 pole pairs: 1666.7 µs) and restarts the counter."""
    desc = load_board(board_file(tmp_path, 'pins = ["PB6", "PB7", "PB8"]\ntimer = "TIM4"\n'))
    link = BoardLink(build_fw("hall_tim"), desc, ts_s=TS, pole_pairs=POLE_PAIRS)
    first, last = run(link, 1500.0, 600, 0.05)
    count = word(link, "captures_n")
    assert count == crossings(first, last, 0.0) >= 15
    captures = recorded(link, "captures", count, 4)
    assert all(c in (1666, 1667) for c in captures[1:]), captures  # the first: from the timer's start
    timer = link.board.peripherals["TIM4"]
    assert timer.hall_captures == count  # type: ignore[attr-defined]


def test_reset_mode_without_hall_sensors_on_the_timer_is_named(build_fw: Callable[..., Path]) -> None:
    link = BoardLink(build_fw("hall_tim"), load_board(), ts_s=TS, pole_pairs=POLE_PAIRS)
    error = str(link.boot_error)  # the start-up stopped there: the run's first Measurement ends it (exit 3)
    assert error.startswith("TIM4.SMCR: reset mode on TI1F_ED (the hall interface), but the board description wires "
                            "no hall sensors to TIM4 ([hall] timer), at pc 0x080")


def test_the_halls_hold_the_angle_in_idle_periods(build_fw: Callable[..., Path], tmp_path: Path) -> None:
    """Idle periods (frames outside a control period) hold the hall levels where the last period left the rotor:
    no edge back and forth; the next Measurement at the angle it left goes on without a spurious edge."""
    from pmsm_hil.protocol.messages import ConfigParam

    desc = load_board(board_file(tmp_path, 'pins = ["PB6", "PB7", "PB8"]\n'))
    link = BoardLink(build_fw("hall"), desc, ts_s=TS, pole_pairs=POLE_PAIRS)
    first, last = run(link, 1500.0, 300, 0.05)
    edges = word(link, "edges")
    link.send(CODEC.encode(ConfigParam(param_id=3, value=1.0)))  # no bus: acked by the board, no idle period
    for _ in range(10):
        link._idle_period()  # the periods a frame outside the control periods would get
    assert link.idle_periods == 10 and word(link, "edges") == edges
    assert link._trajectory(link.board.now)[0] == pytest.approx(last, abs=1e-4)  # the wire's angle resolution
    assert edges == crossings(first, last, 0.0)


def test_an_output_pins_own_edge_is_taken_at_the_store_that_makes_it(bus: FakeBus) -> None:
    """EXTI on a pin the firmware drives itself (PA5 as an output): the pin's input stage follows ODR, so the edge
    of a BSRR, BRR or ODR store sets PR1 and pends the line at the store's cycle, not at the next sample; MODER
    switching the pin to an output with ODR high is an edge too."""
    bus.add("SYSCFG")
    gpioa = bus.add_model("GPIOA", GpioPort)
    exti = bus.add_model("EXTI", Exti)
    pin5 = 1 << 5
    moder = gpioa.read(0x00, 4, 0)
    exti.write(0x08, 4, pin5, 0)                                 # RTSR1: rising (EXTICR2 reset: EXTI5 on port A)
    exti.write(0x00, 4, 0xFF82_0000 | pin5, 0)                   # IMR1
    gpioa.write(0x14, 4, pin5, 10)                               # ODR high while the pin is analog: no level yet
    assert exti.read(0x14, 4, 10) == 0 and bus.pended == []
    gpioa.write(0x00, 4, (moder & ~(3 << 10)) | 1 << 10, 20)      # MODER: PA5 an output, ODR high: a rising edge
    assert exti.read(0x14, 4, 20) == pin5 and bus.pended == [23] and exti.edges[5] == 1
    exti.write(0x14, 4, pin5, 30)
    gpioa.write(0x28, 4, pin5, 40)                               # BRR: falling, not selected
    assert exti.read(0x14, 4, 40) == 0 and exti.edges[5] == 1
    gpioa.write(0x18, 4, pin5, 50)                               # BSRR set: rising, at once
    assert exti.read(0x14, 4, 50) == pin5 and exti.edges[5] == 2 and bus.pended == [23, 23]
    exti.write(0x14, 4, pin5, 60)
    exti.write(0x0C, 4, pin5, 60)                                # FTSR1 too
    gpioa.write(0x18, 4, pin5 << 16, 70)                         # BSRR reset: falling
    gpioa.write(0x14, 4, 0, 80)                                  # ODR already low: no edge
    assert exti.edges[5] == 3 and exti.read(0x14, 4, 80) == pin5
