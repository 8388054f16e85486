"""The board's fast paths against their references — the C paths (c/exc_frame.c: exception entry and return, the
DWT page's reads as a C MMIO callback) against the Python ones (exceptions.py, scs.py), and the scheduler that
skips the quiet models (Board.SKIP_QUIET) against the one that asks every model at every step: the same records,
bit for bit — every Command's frame, the handler cycles, sleep cycles, entries and late compares per period, each
exception's handler times and latencies, the core's registers and SRAM at the end — for the example firmware
(examples/stm32g4_foc and its LATE_ISR variant), the FPU-using test firmwares and the fault variants (the same
fault report)."""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from unicorn import arm_const as arm

from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.messages import Measurement
from pmsm_hil.sim_target.fw_build import build_firmware, missing_tools
from pmsm_hil.sim_target.stm32g4 import periph_native
from pmsm_hil.sim_target.stm32g4.board import Board
from pmsm_hil.sim_target.stm32g4.board_file import load_board
from pmsm_hil.sim_target.stm32g4.cpu import Cpu
from pmsm_hil.sim_target.stm32g4.link import BoardLink
from pmsm_hil.sim_target.stm32g4.part import PARTS
from pmsm_hil.sim_target.stm32g4.peripherals import tim_gp
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import Tim1

TS = 50e-6
PERIODS = 300
EXAMPLE_BOARD = Path(__file__).resolve().parents[2] / "examples" / "stm32g4_foc" / "board.toml"
CORE_REGS = (*(getattr(arm, f"UC_ARM_REG_R{i}") for i in range(13)), arm.UC_ARM_REG_MSP, arm.UC_ARM_REG_PSP,
             arm.UC_ARM_REG_LR, arm.UC_ARM_REG_PC, arm.UC_ARM_REG_XPSR, arm.UC_ARM_REG_CONTROL,
             *(getattr(arm, f"UC_ARM_REG_S{i}") for i in range(32)), arm.UC_ARM_REG_FPSCR)


#: the board's fast paths, each against its reference: (the switch's owner, the switch, what differs when a record
#: does)
FAST_PATHS: dict[str, tuple[Any, str, str]] = {
    "native_exc": (Board, "NATIVE", "the C and the Python exception frames"),
    "quiet_skip": (Board, "SKIP_QUIET", "the skipping and the reference scheduler"),
    "native_core": (Board, "NATIVE_CORE", "the C and the Python scheduler, NVIC and SysTick"),
    "event_driven": (Board, "EVENT_DRIVEN", "the C scheduler caching the event-driven models' next events and the "
                     "one asking them at every step"),
    "native_periph": (periph_native, "NATIVE", "the C and the Python TIM1 and ADC models"),
    "native_encoder": (tim_gp, "NATIVE_ENCODER", "the encoder timer's CNT read in C and in Python"),
    "lazy_stats": (Board, "LAZY_STATS", "the ISR statistics taken from the C core's log when read with the entries "
                   "counted in C and the log drained after every run_until with the entries summed"),
    "native_period": (BoardLink, "NATIVE_PERIOD", "the board link's common period in C and in Python"),
    "count_cache": (Cpu, "COUNT_CACHE", "the instruction counter keeping each flash block's count and the one "
                    "decoding every block it runs"),
    "lazy_ram_exec": (Cpu, "LAZY_RAM_EXEC", "the SRAMs made executable at the first fetch from them and executable "
                      "from the start"),
    "virtual_tlb": (Cpu, "VIRTUAL_TLB", "Unicorn's virtual TLB with the board's fill and the CPU's own TLB fill")}


def records(elf: Path, board_file: str | Path | None, native: bool, monkeypatch: pytest.MonkeyPatch,
            periods: int = PERIODS, skip_quiet: bool = True, native_core: bool = True,
            native_periph: bool = True, event_driven: bool = True,
            native_encoder: bool = True, lazy_stats: bool = True, native_period: bool = True,
            count_cache: bool = True, lazy_ram_exec: bool = True, virtual_tlb: bool = True) -> dict[str, Any]:
    """Everything a run of `periods` Measurements leaves, with the board's C paths (exception frames, the DWT page's
    reads) or the Python reference, with the scheduler skipping quiet models or asking every model every step, with
    the scheduler, NVIC and SysTick in C or in Python, with TIM1 and the ADCs in C or in Python."""
    monkeypatch.setattr(Board, "NATIVE", native)
    monkeypatch.setattr(Board, "SKIP_QUIET", skip_quiet)
    monkeypatch.setattr(Board, "NATIVE_CORE", native_core)
    monkeypatch.setattr(Board, "EVENT_DRIVEN", event_driven)
    monkeypatch.setattr(periph_native, "NATIVE", native_periph)
    monkeypatch.setattr(tim_gp, "NATIVE_ENCODER", native_encoder)
    monkeypatch.setattr(Board, "LAZY_STATS", lazy_stats)
    monkeypatch.setattr(BoardLink, "NATIVE_PERIOD", native_period)
    monkeypatch.setattr(Cpu, "COUNT_CACHE", count_cache)
    monkeypatch.setattr(Cpu, "LAZY_RAM_EXEC", lazy_ram_exec)
    monkeypatch.setattr(Cpu, "VIRTUAL_TLB", virtual_tlb)
    link = BoardLink(elf, load_board(board_file), ts_s=TS, pole_pairs=4)
    assert bool(link._ps.enabled) == (native_period and link.board._lazy_stats and native_periph
                                      and link.boot_error is None and link.halls is None)
    assert (link._c_encoder is not None) == (native_encoder and link.desc.encoder_timer == "TIM3")
    assert (link.board.exceptions._native is not None) == native
    assert link.board._lazy_stats == (lazy_stats and link.board._native_core)
    assert hasattr(link.board, "_dwt") == native
    assert link.board._native_core == (native and skip_quiet and native_core)
    assert link.board.cpu.counter.n_fixed == (2 if count_cache else 0)
    assert link.board.cpu.ram_exec.value == (0 if lazy_ram_exec else 1)
    assert (link.board.cpu.unmapped_ranges() == [(1, 0)]) != virtual_tlb
    assert all(getattr(link.board.peripherals[name], "native_page", None) is not None or name == "ADC2"
               for name in ("TIM1", "ADC1")) == native_periph
    assert (type(link.board.peripherals["TIM1"]) is not Tim1) == native_periph
    if link.board._native_core:  # the models in C are called by the C core directly, not in its Python batches
        assert all(bool(link.board._core.models[link.board._slot[link.board.peripherals[name]]].python)
                   != native_periph for name in ("TIM1", "ADC1", "ADC2"))
        assert all(bool(link.board._core.models[link.board._slot[link.board.peripherals[name]]].event_driven)
                   == event_driven for name in ("FDCAN1", "IWDG"))
    assert (link._adc_table is not None) == native_periph  # the ADC codes from the pin-voltage table
    codec = FrameCodec("canfd")
    frames: list[bytes] = []
    error = ""
    try:
        for k in range(periods):
            th = (2 * math.pi * 50.0 * k * TS) % (2 * math.pi)
            m = Measurement(seq=k, i_a=10 * math.cos(th), i_b=10 * math.cos(th - 2.094),
                            i_c=10 * math.cos(th + 2.094), theta_e=th, omega_m=78.5, vdc=48.0)
            link.send(codec.encode(m))
            while (frame := link.poll()) is not None:
                frames.append(bytes(frame.data))
    except BoardError as exc:
        error = str(exc)
    board = link.board
    sram = board.read_memory(0x2000_0000, board.part.sram_size)
    return {"frames": frames, "error": error, "first_late": link.late_first_period, "periods": link.periods,
            "wall": link.wall_s > 0, "in_c": int(link._ps.in_c), "frames_tx": link.stats.frames_tx,
            "isr": link.isr_cycles, "sleep": link.sleep_cycles,
            "late": link.late_per_period, "entries": link.entries_per_period, "now": board.now,
            "handlers": {e: (s.entries, s.cycles, s.latency) for e, s in board.isr.items()},
            "regs": [board.cpu.reg(r) for r in CORE_REGS], "sram": sram, "boot_error": str(link.boot_error or ""),
            "encoder": [(t.last_edges, t.down, t.anchor, t.anchor_cnt) for t in board.peripherals.values()
                        if isinstance(t, tim_gp.GeneralTimer)]}


#: the records of runs made in a module, per (ELF, board file, periods, the fast path off or "" for none): the side
#: with every fast path on is the one all the comparisons of a firmware share, made once, not once per fast path
Runs = dict[tuple[Path, str, int, str], dict[str, Any]]


@pytest.fixture(scope="module")
def native_runs() -> Runs:
    """The module's runs (see `Runs`), each made at its first use."""
    return {}


def run(runs: Runs, off: str, elf: Path, board_file: str | Path | None, monkeypatch: pytest.MonkeyPatch,
        periods: int = PERIODS) -> dict[str, Any]:
    """A copy of the records of `elf` with the fast path `off` (FAST_PATHS; "": none) replaced by its reference and
    every other one on, made once per module."""
    key = (elf, str(board_file), periods, off)
    if key not in runs:
        runs[key] = records(elf, board_file, off != "native_exc", monkeypatch, periods,
                            skip_quiet=off != "quiet_skip", native_core=off != "native_core",
                            native_periph=off != "native_periph", event_driven=off != "event_driven",
                            native_encoder=off != "native_encoder", lazy_stats=off != "lazy_stats",
                            native_period=off != "native_period", count_cache=off != "count_cache",
                            lazy_ram_exec=off != "lazy_ram_exec", virtual_tlb=off != "virtual_tlb")
    return copy.deepcopy(runs[key])


def same(path: str, elf: Path, board_file: str | Path | None, monkeypatch: pytest.MonkeyPatch,
         native_runs: Runs, periods: int = PERIODS) -> dict[str, Any]:
    """The records of `elf` with the fast path `path` (FAST_PATHS) and with its reference: equal, key by key. The
    fast side (every path on) is the same run for every `path`, made once (`run`)."""
    what = FAST_PATHS[path][2]
    reference = run(native_runs, path, elf, board_file, monkeypatch, periods)
    native = run(native_runs, "", elf, board_file, monkeypatch, periods)
    in_c = reference.pop("in_c")  # the periods the C period ran (none with it off)
    assert in_c == 0 or path != "native_period"
    for key in reference:
        assert native[key] == reference[key], f"{key} differs between {what}"
    return native


@functools.cache
def example(*defines: str) -> Path:
    """The example firmware built with `defines` (from the firmware cache; looked up once per process)."""
    missing = missing_tools("stm32g474")
    if missing:
        pytest.skip(f"firmware board stm32g474: {', '.join(missing)} not installed")
    return build_firmware("stm32g474", defines=list(defines)).path


@pytest.mark.parametrize("path", FAST_PATHS)
@pytest.mark.parametrize("defines", [(), ("LATE_ISR",)], ids=["example", "late_isr"])
def test_the_example_firmware_gives_the_same_records(defines: tuple[str, ...], path: str,
                                                     monkeypatch: pytest.MonkeyPatch,
                                                     native_runs: Runs) -> None:
    out = same(path, example(*defines), EXAMPLE_BOARD, monkeypatch, native_runs)
    assert len(out["frames"]) >= PERIODS and sum(out["entries"]) >= PERIODS and not out["error"]


@pytest.mark.parametrize("path", FAST_PATHS)
def test_the_example_fault_variant_gives_the_same_fault_report(path: str, monkeypatch: pytest.MonkeyPatch,
                                                               native_runs: Runs) -> None:
    # its current loop faults in ISR 300 (FAULT_AT_ISR; the variant's default, ISR 2000, only adds periods the
    # example firmware's comparisons above already make: the Python references' 2100 periods were most of the file)
    out = same(path, example("FAULT", "FAULT_AT_ISR=300u"), EXAMPLE_BOARD, monkeypatch, native_runs, 400)
    assert "CFSR" in out["error"] and len(out["isr"]) < 400


@pytest.mark.parametrize("path", FAST_PATHS)
@pytest.mark.parametrize(("name", "defines"), [("foc_bench", ()), ("pwm_adc", ("LATE",)),
                                                ("pwm_adc", ("FAULT_AT=40",))])
def test_the_test_firmwares_give_the_same_records(name: str, defines: tuple[str, ...], path: str,
                                                  build_fw: Callable[..., Path],
                                                  monkeypatch: pytest.MonkeyPatch, native_runs: Runs) -> None:
    out = same(path, build_fw(name, *defines), None, monkeypatch, native_runs)
    assert sum(out["entries"]) > 0
    assert out["in_c"] > 0 and (out["in_c"] == PERIODS or out["error"])  # TIM1's outputs on: the period in C


@pytest.mark.parametrize("native", [True, False], ids=["c", "python"])
def test_an_unmodelled_dwt_register_is_named_in_one_line(native: bool, build_fw: Callable[..., Path],
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(Board, "NATIVE", native)
    board = Board(PARTS["stm32g474"], build_fw("errors", "UNMODELLED_DWT"))
    with pytest.raises(BoardError) as info:
        board.run_until(1_000_000)
    text = str(info.value)
    assert "0xe0001200" in text.lower() and "touch_dwt_reserved" in text and "\n" not in text


@pytest.mark.parametrize("names", [("FDCAN1",), ("TIM1", "ADC2")], ids=["fdcan1", "tim1_group"])
def test_models_behind_the_c_ops_give_the_same_records(names: tuple[str, ...], monkeypatch: pytest.MonkeyPatch,
                                                       native_runs: Runs) -> None:
    """A model in the C scheduler's ops list (hil_periph_ops_t, as a model written in C sits there: called directly,
    between the batches of the Python models) — here Python models behind trampolines of that signature, one outside
    the TIM1/ADC group, and TIM1 and ADC2 with ADC1 in a batch between them — leaves the Python scheduler's records."""
    from pmsm_hil.sim_target.stm32g4.core_native import trampoline_ops
    from pmsm_hil.sim_target.stm32g4.peripherals.base import REGISTRY

    elf = example()
    reference = run(native_runs, "native_core", elf, EXAMPLE_BOARD, monkeypatch)  # the Python scheduler's
    from pmsm_hil.sim_target.stm32g4.peripherals.adc_native import NativeAdc2
    from pmsm_hil.sim_target.stm32g4.peripherals.tim1_native import NativeTim1

    in_c = {"TIM1": NativeTim1, "ADC2": NativeAdc2}  # the models in C have ops of their own: behind trampolines here
    for name in names:
        for cls in (REGISTRY[name], in_c.get(name)):
            if cls is not None:
                monkeypatch.setattr(cls, "native_ops", property(
                    lambda self: trampoline_ops(self, self.bus.cpu.hook_failed)), raising=False)
    out = records(elf, EXAMPLE_BOARD, True, monkeypatch)
    for key in reference:
        assert out[key] == reference[key], f"{key} differs with {names} behind the C ops"
    assert len(out["frames"]) >= PERIODS


def test_one_long_call_fills_and_drains_the_cores_sample_log(monkeypatch: pytest.MonkeyPatch) -> None:
    """One run_until over 3000 periods takes more exception entries and returns than the C core's sample log holds
    (core_native.LOG_MAX): the loop hands back, the samples move into Board.isr and it resumes — the Python
    scheduler's statistics, cycle and sleep counts."""
    from pmsm_hil.sim_target.stm32g4.core_native import LOG_MAX
    from pmsm_hil.sim_target.stm32g4.link import BoardLink

    elf, seen = example(), []
    for native_core in (False, True):
        monkeypatch.setattr(Board, "NATIVE_CORE", native_core)
        link = BoardLink(elf, load_board(EXAMPLE_BOARD), ts_s=TS, pole_pairs=4)
        board = link.board
        board.run_until(board.now + 3000 * link.period_cycles)
        seen.append(({e: (s.entries, s.cycles, s.latency) for e, s in board.isr.items()}, board.now,
                     board.sleep_cycles, board.handler_cycles))
    assert seen[1] == seen[0]
    assert 2 * sum(entries for entries, _, _ in seen[1][0].values()) > LOG_MAX


def test_the_period_in_c_hands_back_and_resumes_over_a_long_run(build_fw: Callable[..., Path],
                                                                  monkeypatch: pytest.MonkeyPatch,
                                                                  native_runs: Runs) -> None:
    """Over 3000 periods the C core's sample log fills (the period in C hands its run back to Python, which drains
    the log and finishes the period) and the C period's rings are read into the lists several times: the records of
    the Python reference."""
    out = same("native_period", build_fw("foc_bench"), None, monkeypatch, native_runs, 3000)
    assert 0 < out["in_c"] < 3000 and len(out["isr"]) == 3000
