"""ADC1 and ADC2 with their state and behaviour in C (c/adc.c): the interface of the Python reference (adc.Adc1,
adc.Adc2, which make these when periph_native.NATIVE is set), every method a call into the library; the pair shares
one C struct (the ADC1_2 line, the clock of ADC12_COMMON.CCR, the register page the library's MMIO callbacks
serve). A conversion's code (the board's analog front end, the OPAMPs) and a regular conversion's DMA request stay
in Python (the reference's `_code`, DMAMUX1), called back from C."""

from __future__ import annotations

import ctypes
import weakref
from collections.abc import Sequence
from typing import Any, ClassVar

from pmsm_hil.sim_target.stm32g4 import periph_native as pn
from pmsm_hil.sim_target.stm32g4.core_native import PeriphOps
from pmsm_hil.sim_target.stm32g4.counter import CounterState
from pmsm_hil.sim_target.stm32g4.peripherals.adc import ADC1_2_IRQ, CFGR, JSQR, Adc, Adc1, Adc2, Conversion
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardBus, BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.regs import lane
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import SIGNALS
from pmsm_hil.sim_target.stm32g4.peripherals.tim1_native import CRegs

_I64, _U32, _INT, _P = ctypes.c_int64, ctypes.c_uint32, ctypes.c_int, ctypes.c_void_p
CODE_FN = ctypes.CFUNCTYPE(ctypes.c_uint32, ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_int64)
DMA_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_int64)
QUEUE_MAX = 64


class ConvState(ctypes.Structure):
    _fields_ = [("sample_at", _I64), ("done_at", _I64), ("injected", ctypes.c_int32), ("rank", ctypes.c_int32),
                ("channel", ctypes.c_int32), ("last", ctypes.c_int32)]


class SampleState(ctypes.Structure):
    _fields_ = [("at", _I64), ("channel", ctypes.c_int32), ("code", ctypes.c_uint32)]


class AdcState(ctypes.Structure):
    """Mirror of hil_adc_t (c/adc.c)."""

    _fields_ = [("regs", ctypes.c_uint32 * 64), ("present", ctypes.c_uint8 * 64), ("cal_done_at", _I64),
                ("ready_at", _I64), ("triggers", _I64), ("samples", _I64), ("ready", ctypes.c_int32),
                ("index", ctypes.c_int32), ("n_queue", ctypes.c_int32), ("error", ctypes.c_int32),
                ("queue", ConvState * QUEUE_MAX), ("log", SampleState * 64), ("pair", _P)]


class Adc12State(ctypes.Structure):
    """Mirror of hil_adc12_t (c/adc.c)."""

    _fields_ = [("adc", AdcState * 2), ("common_ccr", ctypes.c_uint32), ("irq", ctypes.c_int32),
                ("line_on", ctypes.c_int32), ("table_on", ctypes.c_int32), ("vref", ctypes.c_double),
                ("volts", (ctypes.c_double * 32) * 2),
                ("sink", pn.IrqSink), ("code", CODE_FN), ("dma", DMA_FN), ("callback_user", _P), ("count", _P),
                ("fallback_read", _P), ("fallback_write", _P), ("fallback_user", _P), ("ops", pn.PeriphOps * 2)]


#: the inputs a front end in C holds (FRONT_MAX of c/adc.c)
FRONT_MAX = 32


class FrontEnd(ctypes.Structure):
    """Mirror of hil_adc_front_t (c/adc.c): a noiseless analog front end of ADC1/ADC2 pins."""

    _fields_ = [("pair", _P), ("n", ctypes.c_int32), ("adc", ctypes.c_int32 * FRONT_MAX),
                ("channel", ctypes.c_int32 * FRONT_MAX), ("signal", ctypes.c_int32 * FRONT_MAX),
                ("offset", ctypes.c_double * FRONT_MAX), ("gain", ctypes.c_double * FRONT_MAX),
                ("vref", ctypes.c_double), ("vrefint", ctypes.c_double)]


def _typed(lib: ctypes.CDLL) -> ctypes.CDLL:
    if not getattr(lib, "_hil_typed", False):
        lib.hil_adc_next_event.argtypes, lib.hil_adc_next_event.restype = [_P, _I64], _I64
        lib.hil_adc_advance.argtypes, lib.hil_adc_advance.restype = [_P, _I64], None
        lib.hil_adc_load.argtypes, lib.hil_adc_load.restype = [_P, _INT, _I64], _U32
        lib.hil_adc_store.argtypes, lib.hil_adc_store.restype = [_P, _INT, _U32, _I64], _INT
        lib.hil_adc_on_trigger.argtypes, lib.hil_adc_on_trigger.restype = [_P, _INT, _INT, _I64], None
        lib.hil_adc_cycles_per_clock.argtypes, lib.hil_adc_cycles_per_clock.restype = [_P], ctypes.c_double
        lib.hil_adc_init.argtypes, lib.hil_adc_init.restype = [_P], None
        lib.hil_adc_code_of.argtypes = [_P, ctypes.c_double, ctypes.c_double]
        lib.hil_adc_code_of.restype = _U32
        lib.hil_adc_front_take.argtypes, lib.hil_adc_front_take.restype = [_P, _P], None
        for name, struct in (("hil_adc_size", Adc12State), ("hil_adc_one_size", AdcState),
                             ("hil_adc_front_size", FrontEnd)):
            fn = getattr(lib, name)
            fn.argtypes, fn.restype = [], ctypes.c_uint
            if fn() != ctypes.sizeof(struct):
                raise pn.PeriphBuildError(f"c/adc.c and periph_native's {struct.__name__} differ in size")
        lib._hil_typed = True  # type: ignore[attr-defined]
    return lib


class Adc12Pair:
    """The C struct of one board's ADC1 and ADC2 and the Python functions it calls back (holding the board and the
    models weakly: the pair lives as long as its board, `pair_of`)."""

    def __init__(self, bus: BoardBus) -> None:
        self.lib = _typed(pn.library("adc"))
        self.state = Adc12State()
        self.callbacks = pn.Callbacks()
        self.adcs: list[weakref.ReferenceType[NativeAdc] | None] = [None, None]
        s, cb = self.state, self.callbacks
        s.irq = ADC1_2_IRQ
        board = weakref.ref(bus)
        s.sink = cb.sink(lambda irq: board().set_pending(irq),  # type: ignore[union-attr]
                         lambda irq: board().clear_pending(irq))  # type: ignore[union-attr]
        s.code = cb.keep(CODE_FN(self._code))
        s.dma = cb.keep(DMA_FN(cb.guard(self._dma)))
        self.lib.hil_adc_init(ctypes.addressof(s))
        self._front_end: tuple[FrontEnd, Any] | None = None

    def set_inputs(self, vref_v: float, volts: dict[tuple[str, int], float]) -> None:
        """Take each conversion's code from `volts` ((ADC name, channel) -> the pin's voltage [V], 0 V for one not
        named) and VREF+ `vref_v` [V] in C, with no call into Python: for a front end without noise and without
        OPAMP inputs, whose values hold for the period (a link calls this, or writes the struct's table, once a
        period)."""
        s = self.state
        ctypes.memset(ctypes.addressof(s.volts), 0, ctypes.sizeof(s.volts))
        for (adc, channel), v in volts.items():
            if adc not in ("ADC1", "ADC2") or not 0 <= channel < 32:
                raise BoardError(f"ADC input {adc} channel {channel}: the table holds ADC1/ADC2 channels 0-31")
            s.volts[0 if adc == "ADC1" else 1][channel] = v
        s.vref = vref_v
        s.table_on = 1

    def set_front_end(self, inputs: Sequence[tuple[str, int, float, float, int]], n_signals: int, vref_v: float,
                      vrefint_v: float) -> None:
        """The noiseless front end `take` computes the table from: per input (ADC name, channel, offset [V], gain [V
        per unit], the index of its signal among `take`'s `n_signals` values; at most FRONT_MAX), later inputs on the
        same pin winning; VREF+ `vref_v` and VREFINT (ADC1 IN18) `vrefint_v` [V]."""
        if len(inputs) > FRONT_MAX:
            raise BoardError(f"ADC inputs: {len(inputs)} analog inputs, the table's front end holds {FRONT_MAX}")
        front = FrontEnd()
        front.pair, front.n, front.vref, front.vrefint = ctypes.addressof(self.state), len(inputs), vref_v, vrefint_v
        for k, (adc, channel, offset, gain, signal) in enumerate(inputs):
            if adc not in ("ADC1", "ADC2") or not 0 <= channel < 32:
                raise BoardError(f"ADC input {adc} channel {channel}: the table holds ADC1/ADC2 channels 0-31")
            if not 0 <= signal < n_signals:
                raise BoardError(f"ADC input {adc} channel {channel}: signal index {signal} outside 0-{n_signals - 1}")
            front.adc[k], front.channel[k], front.offset[k], front.gain[k], front.signal[k] = (
                0 if adc == "ADC1" else 1, channel, offset, gain, signal)
        self._front_end = (front, (ctypes.c_double * n_signals)())

    def take(self, values: Sequence[float]) -> None:
        """The period's pin voltages from the front end (`set_front_end`) at signal values `values` into the table,
        in one call (as `set_inputs` with each input's offset + gain x value)."""
        if self._front_end is None:
            raise BoardError("Adc12Pair.take before set_front_end")
        front, table = self._front_end
        table[:] = values
        self.lib.hil_adc_front_take(ctypes.addressof(front), table)

    def take_function(self) -> tuple[int, int]:
        """(address of hil_adc_front_take, its front end) for a caller in C that fills the table itself (`take`
        without Python)."""
        if self._front_end is None:
            raise BoardError("Adc12Pair.take_function before set_front_end")
        return pn.address(self.lib.hil_adc_front_take), ctypes.addressof(self._front_end[0])

    def clear_inputs(self) -> None:
        """Take each conversion's code from the board's analog front end again (Adc._code, in Python)."""
        self.state.table_on = 0

    def _code(self, _user: int, index: int, channel: int, at: int) -> int:
        try:
            return self._adc(index)._code(channel, at)
        except BaseException as exc:  # raised by the model after the C call (Callbacks.check)
            if self.callbacks.error is None:
                self.callbacks.error = exc
            pn.HELD.value = 1
            return 0

    def _adc(self, index: int) -> NativeAdc:
        ref = self.adcs[index]
        adc = None if ref is None else ref()
        if adc is None:
            raise BoardError(f"ADC{index + 1} converts but is no longer on its board")
        return adc

    def _dma(self, _user: int, index: int, at: int) -> None:
        adc = self._adc(index)
        adc.bus.peripheral("DMAMUX1").request(adc.dma_request, at)  # type: ignore[attr-defined]


_PAIRS: weakref.WeakKeyDictionary[Any, Adc12Pair] = weakref.WeakKeyDictionary()


def pair_of(bus: BoardBus) -> Adc12Pair:
    """The ADC pair's C state on board `bus` (made on first use)."""
    pair = _PAIRS.get(bus)
    if pair is None:
        pair = _PAIRS[bus] = Adc12Pair(bus)
    return pair


def _at(value: int) -> int | None:
    return None if value < 0 else int(value)


class NativeAdc(Adc):
    """One ADC of the pair in C (the Python reference's interface; its docstring says what is modelled)."""

    IS_NATIVE: ClassVar[bool] = True
    native_page: ClassVar[int | None] = None

    def reset(self) -> None:
        pair = self._pair_state = pair_of(self.bus)
        self._lib = pair.lib
        index = 0 if self.base == Adc1.base else 1
        pair.adcs[index] = weakref.ref(self)
        a = self._a = pair.state.adc[index]
        self._p = ctypes.addressof(a)
        self._cb = pair.callbacks
        ctypes.memset(ctypes.addressof(a.regs), 0, ctypes.sizeof(a.regs) + ctypes.sizeof(a.present))
        for word, value in self.RESET.items():
            a.regs[word >> 2] = value
            a.present[word >> 2] = 1
        a.cal_done_at = a.ready_at = -1
        a.triggers = a.samples = 0
        a.ready = a.n_queue = a.error = 0
        self.regs = CRegs(a.regs, frozenset(self.RESET))  # type: ignore[assignment]
        self._subscribed: tuple[str, ...] = ()
        self._common_model = None
        self._keep: list[Any] = []

    # --- the state the reference keeps in attributes --------------------------------------------------------------

    @property
    def cal_done_at(self) -> int | None:  # type: ignore[override]
        return _at(self._a.cal_done_at)

    @property
    def ready_at(self) -> int | None:  # type: ignore[override]
        return _at(self._a.ready_at)

    @property
    def ready(self) -> bool:  # type: ignore[override]
        return bool(self._a.ready)

    @property
    def triggers(self) -> int:  # type: ignore[override]
        return int(self._a.triggers)

    @property
    def queue(self) -> list[Conversion]:  # type: ignore[override]
        a = self._a
        return [Conversion(bool(c.injected), c.rank, c.channel, c.sample_at, c.done_at, bool(c.last))
                for c in a.queue[:a.n_queue]]

    @property
    def sample_log(self) -> list[tuple[int, int, int]]:  # type: ignore[override]
        """(cycle, channel, code) of the recent injected samples (the last 64)."""
        a = self._a
        n = min(int(a.samples), 64)
        return [(int(s.at), int(s.channel), int(s.code))
                for s in (a.log[(a.samples - n + i) % 64] for i in range(n))]

    # --- behaviour: the library's ----------------------------------------------------------------------------------

    def cycles_per_adc_clock(self) -> float:
        return float(self._lib.hil_adc_cycles_per_clock(self._p))

    def next_event(self, now: int) -> int | None:
        at = self._lib.hil_adc_next_event(self._p, now)
        return None if at < 0 else int(at)

    def advance(self, now: int) -> None:
        self._lib.hil_adc_advance(self._p, now)
        if self._cb.error is not None or self._a.error:
            self._raise()

    def _raise(self) -> None:
        if self._a.error:
            self._a.error = 0
            raise BoardError(f"{self.name}: more than {QUEUE_MAX} conversions queued (the triggers come faster "
                             "than the sequences convert)")
        self._cb.check()

    def on_trigger(self, signal: str, rising: bool, at: int) -> None:
        self._lib.hil_adc_on_trigger(self._p, SIGNALS.index(signal), int(rising), at)
        if self._cb.error is not None or self._a.error:
            self._raise()

    def c_listener(self) -> tuple[int, int]:
        """(function, user) of this ADC as a listener of TIM1 in C."""
        return pn.address(self._lib.hil_adc_on_trigger), self._p

    def read(self, offset: int, size: int, now: int) -> int:
        word = offset & ~3
        if word not in self.regs:
            self.word(offset, "read")  # raises naming the register
        return lane(self.load(word, now), offset, size)

    def load(self, word: int, now: int) -> int:
        value = int(self._lib.hil_adc_load(self._p, word >> 2, now))
        if self._cb.error is not None or self._a.error:
            self._raise()
        return value

    def store(self, word: int, value: int, now: int) -> None:
        status = self._lib.hil_adc_store(self._p, word >> 2, value & 0xFFFF_FFFF, now)
        if self._cb.error is not None or self._a.error:
            self._raise()
        if status == 1:
            raise BoardError(f"{self.name}.CR.ADCAL set while ADEN = 1 (RM0440 21.4.8: calibrate disabled)")
        if status == 2:
            raise BoardError(f"{self.name}.CR.ADCAL: the voltage regulator is off (ADVREGEN = 0 or DEEPPWD = 1)")
        if word in (JSQR, CFGR):
            self._subscribe()

    def c_ops(self) -> int:
        """Address of this ADC's hil_periph_ops_t (c/periph_ops.h): next_event / advance without Python."""
        state = self._pair_state.state
        index = 0 if self._p == ctypes.addressof(state.adc[0]) else 1
        return ctypes.addressof(state) + Adc12State.ops.offset + index * ctypes.sizeof(pn.PeriphOps)

    @property
    def native_ops(self) -> PeriphOps:
        """This ADC's hil_periph_ops_t as the board's C core holds it (called without Python)."""
        return PeriphOps.from_address(self.c_ops())

    def set_irq_sink(self, board: int, assert_line: int, withdraw_line: int, touched: int = 0) -> None:
        """Raise ADC1_2 through C functions (an NVIC in C: periph_native.set_sink); the pair shares the line;
        `touched`: the scheduler in C that hears of the accesses the library's MMIO callbacks serve."""
        pn.set_sink(self._pair_state.state.sink, board, assert_line, withdraw_line, touched)

    def raise_held(self) -> None:
        """Raise what happened while the C core called the model directly (a full conversion queue, a Python
        listener's exception)."""
        if self._cb.error is not None or self._a.error:
            self._raise()

    def map_native(self, cpu: Any, read: Any, write: Any) -> None:
        """Serve the ADC page (ADC1, ADC2; ADC12_COMMON through `read`/`write`, the board's decoder) from the library
        on `cpu`."""
        state = self._pair_state.state
        state.count = ctypes.addressof(cpu.counter) + CounterState.count.offset
        self._keep = pn.map_page(cpu, 0x5000_0000, 0x1000, read, write, pn.address(self._lib.hil_adc_mmio_read),
                                 pn.address(self._lib.hil_adc_mmio_write), state)


class NativeAdc1(NativeAdc, Adc1):
    native_page = 0x5000_0000


class NativeAdc2(NativeAdc, Adc2):
    pass


NATIVE_CLASSES: dict[str, type[NativeAdc]] = {"ADC1": NativeAdc1, "ADC2": NativeAdc2}
