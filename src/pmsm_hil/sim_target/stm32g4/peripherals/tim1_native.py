"""TIM1 with its state and behaviour in C (c/tim1.c): the interface of the Python reference (tim1.Tim1, which
makes one of these when periph_native.NATIVE is set), every method a call into the library; its register page
served by the library's MMIO callbacks (the board maps them: `native_page`, `map_native`)."""

from __future__ import annotations

import ctypes
from collections.abc import Iterator, MutableMapping, Sequence
from typing import Any

from pmsm_hil.sim_target.stm32g4 import periph_native as pn
from pmsm_hil.sim_target.stm32g4.core_native import PeriphOps
from pmsm_hil.sim_target.stm32g4.counter import CounterState
from pmsm_hil.sim_target.stm32g4.part import IRQ
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.regs import lane
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import SIGNALS, Listener, Tim1

#: hil_tim1_store's refusals
_ERRORS = {1: "TIM1.BDTR.BK2E: the second break input BRK2 is not modelled",
           2: "TIM1.EGR: only UG (bit 0) is modelled",
           3: "TIM1.SMCR.SMS: slave and encoder modes of TIM1 are not modelled",
           4: "TIM1.CR1.OPM: one-pulse mode is not modelled"}
_I64, _U32, _INT, _P = ctypes.c_int64, ctypes.c_uint32, ctypes.c_int, ctypes.c_void_p


def _typed(lib: ctypes.CDLL) -> ctypes.CDLL:
    if not getattr(lib, "_hil_typed", False):
        lib.hil_tim1_next_event.argtypes, lib.hil_tim1_next_event.restype = [_P, _I64], _I64
        lib.hil_tim1_advance.argtypes, lib.hil_tim1_advance.restype = [_P, _I64], None
        lib.hil_tim1_counter.argtypes, lib.hil_tim1_counter.restype = [_P, _I64], _I64
        lib.hil_tim1_load.argtypes, lib.hil_tim1_load.restype = [_P, _INT, _I64], _U32
        lib.hil_tim1_store.argtypes, lib.hil_tim1_store.restype = [_P, _INT, _U32, _I64], _INT
        lib.hil_tim1_trip_break.argtypes, lib.hil_tim1_trip_break.restype = [_P], None
        lib.hil_tim1_break_active.argtypes, lib.hil_tim1_break_active.restype = [_P], _INT
        lib.hil_tim1_set_break_pin.argtypes, lib.hil_tim1_set_break_pin.restype = [_P, _INT, _I64], None
        lib.hil_tim1_subscribe.argtypes, lib.hil_tim1_subscribe.restype = [_P, _INT, _P, _P], _INT
        lib.hil_tim1_unsubscribe.argtypes, lib.hil_tim1_unsubscribe.restype = [_P, _P, _P], None
        lib.hil_tim1_init.argtypes, lib.hil_tim1_init.restype = [_P], None
        lib.hil_tim1_size.argtypes, lib.hil_tim1_size.restype = [], ctypes.c_uint
        lib.hil_tim1_compare_duties.argtypes = [_P, _INT, _P, _P, ctypes.c_double, ctypes.c_double, _P]
        lib.hil_tim1_compare_duties.restype = _INT
        lib.hil_tim1_outputs_size.argtypes, lib.hil_tim1_outputs_size.restype = [], ctypes.c_uint
        if lib.hil_tim1_outputs_size() != ctypes.sizeof(OutputsState):
            raise pn.PeriphBuildError("c/tim1.c's hil_tim1_outputs_t and tim1_native.OutputsState differ in size")
        if lib.hil_tim1_size() != ctypes.sizeof(pn.Tim1State):
            raise pn.PeriphBuildError("c/tim1.c's hil_tim1_t and periph_native.Tim1State differ in size")
        lib._hil_typed = True  # type: ignore[attr-defined]
    return lib


class OutputsState(ctypes.Structure):
    """Mirror of hil_tim1_outputs_t (c/tim1.c)."""

    _fields_ = [("tim", _P), ("n", ctypes.c_int32), ("channels", ctypes.c_int32 * 6), ("hclk_hz", ctypes.c_double),
                ("carrier_s", ctypes.c_double)]


class CRegs(MutableMapping[int, int]):
    """A model's registers by word offset, stored in its C struct's `regs` (the modelled offsets only)."""

    def __init__(self, array: Any, words: frozenset[int]) -> None:
        self._array = array
        self._words = words

    def __getitem__(self, word: int) -> int:
        if word not in self._words:
            raise KeyError(word)
        return int(self._array[word >> 2])

    def __setitem__(self, word: int, value: int) -> None:
        if word not in self._words:
            raise KeyError(word)
        self._array[word >> 2] = value & 0xFFFF_FFFF

    def __delitem__(self, word: int) -> None:
        raise TypeError("a register cannot be removed")

    def __contains__(self, word: object) -> bool:
        return word in self._words

    def __iter__(self) -> Iterator[int]:
        return iter(sorted(self._words))

    def __len__(self) -> int:
        return len(self._words)


def _field(name: str, doc: str) -> property:
    def get(self: NativeTim1) -> int:
        return int(getattr(self._s, name))
    return property(get, doc=doc)


class NativeTim1(Tim1):
    """TIM1 in C (the Python reference's interface; its docstring says what is modelled)."""

    #: the 4 KiB page whose MMIO callbacks are the library's (TIM1 at 0x40012C00)
    native_page = 0x4001_2000

    def reset(self) -> None:
        lib = self._lib = _typed(pn.library("tim1"))
        s = self._s = pn.Tim1State()
        self._p = ctypes.addressof(s)
        self._cb = pn.Callbacks()
        self._py_listeners: dict[Any, Any] = {}
        for word, value in self.RESET.items():
            s.regs[word >> 2] = value
            s.present[word >> 2] = 1
        self.regs = CRegs(s.regs, frozenset(self.RESET))  # type: ignore[assignment]
        s.arr, s.seg_dir, s.last_update, s.last_trigger = 0xFFFF, 1, -1, -1
        s.first_late_update, s.late_counted_at, s.break_pin = -1, -2, -1
        s.irq_up, s.irq_cc, s.irq_brk = IRQ["TIM1_UP_TIM16"], IRQ["TIM1_CC"], IRQ["TIM1_BRK_TIM15"]
        s.sink = self._cb.sink(self.bus.set_pending, self.bus.clear_pending)
        lib.hil_tim1_init(self._p)
        self._keep: list[Any] = []
        #: compare_duties' arrays: (channels, channels in C, currents, duties)
        self._duty_buffers: tuple[tuple[int, ...], Any, Any, Any] | None = None

    # --- the state the reference keeps in attributes (read by the board link and the metrics) ---------------------

    psc = _field("psc", "active prescaler")
    arr = _field("arr", "active auto-reload")
    rep = _field("rep", "repetition down-counter")
    seg_start = _field("seg_start", "cycle at which the current segment began")
    seg_from = _field("seg_from", "counter value then")
    seg_dir = _field("seg_dir", "+1 up, -1 down")
    done_until = _field("done_until", "events up to this cycle are processed")
    frozen_cnt = _field("frozen_cnt", "the counter while stopped")
    updates = _field("updates", "update events so far")
    last_update = _field("last_update", "cycle of the last update event")
    last_trigger = _field("last_trigger", "cycle of the last ADC trigger this timer emitted")
    late_writes = _field("late_writes", "periods whose compare values landed a period late")
    break_trips = _field("break_trips", "times BRK went active with BKE set")

    @property
    def running(self) -> bool:  # type: ignore[override]
        return bool(self._s.running)

    @property
    def ccr(self) -> list[int]:  # type: ignore[override]
        return list(self._s.ccr)

    @property
    def ocref(self) -> list[bool]:  # type: ignore[override]
        return [bool(v) for v in self._s.ocref]

    @property
    def native_state(self) -> pn.Tim1State:
        """The model's C state (a new struct after each reset): its late-compare counters read directly once a
        period by the board link."""
        return self._s

    @property
    def first_late_update(self) -> int | None:  # type: ignore[override]
        value = int(self._s.first_late_update)
        return None if value < 0 else value

    @property
    def break_pin(self) -> bool | None:  # type: ignore[override]
        value = int(self._s.break_pin)
        return None if value < 0 else bool(value)

    @property
    def listeners(self) -> dict[str, list[Listener]]:  # type: ignore[override]
        out: dict[str, list[Listener]] = {}
        for i, signal in enumerate(SIGNALS):
            for k in range(self._s.n_listeners[i]):
                entry = self._s.listeners[i][k]
                out.setdefault(signal, []).append(self._py_listeners.get((entry.fn, entry.user), entry))
        return out

    # --- behaviour: the library's ----------------------------------------------------------------------------------

    def next_event(self, now: int) -> int | None:
        at = self._lib.hil_tim1_next_event(self._p, now)
        return None if at < 0 else int(at)

    def advance(self, now: int) -> None:
        self._lib.hil_tim1_advance(self._p, now)
        if self._cb.error is not None:
            self._cb.check()

    def counter(self, now: int) -> int:
        value = int(self._lib.hil_tim1_counter(self._p, now))
        self._cb.check()
        return value

    def compare_duties(self, channels: Sequence[int], currents: Sequence[float], hclk_hz: int,
                       carrier_s: float) -> tuple[float, ...] | None:
        """The reference's, in one call into the library (hil_tim1_compare_duties)."""
        buffers = self._duty_buffers
        if buffers is None or (buffers[0] is not channels and buffers[0] != tuple(channels)):
            n = len(channels)
            buffers = self._duty_buffers = (tuple(channels), (ctypes.c_int32 * n)(*channels), (ctypes.c_double * n)(),
                                            (ctypes.c_double * n)())
        _, ch, cur, out = buffers
        cur[:] = currents
        if not self._lib.hil_tim1_compare_duties(self._p, len(ch), ch, cur, hclk_hz, carrier_s, out):
            return None
        return tuple(out)

    def outputs_function(self, channels: Sequence[int], hclk_hz: int, carrier_s: float) -> tuple[int, int]:
        """(address of hil_tim1_outputs, its arguments) for a caller in C: `compare_duties` for these channels,
        clock and carrier period without Python (`int fn(void *user, const double *currents, double *duties)`)."""
        if not 0 < len(channels) <= 6:
            raise BoardError(f"TIM1 outputs: {len(channels)} channels (1 to 6)")
        o = OutputsState()
        o.tim, o.n, o.hclk_hz, o.carrier_s = self._p, len(channels), hclk_hz, carrier_s
        for k, ch in enumerate(channels):
            o.channels[k] = ch
        self._outputs_args = o  # kept alive with the model
        return pn.address(self._lib.hil_tim1_outputs), ctypes.addressof(o)

    @property
    def moe(self) -> bool:
        return bool(self._s.regs[0x11] >> 15 & 1)  # BDTR

    def trip_break(self) -> None:
        self._lib.hil_tim1_trip_break(self._p)
        self._cb.check()

    def break_active(self) -> bool:
        return bool(self._lib.hil_tim1_break_active(self._p))

    def set_break_pin(self, level: bool, now: int) -> None:
        self._lib.hil_tim1_set_break_pin(self._p, int(level), now)
        self._cb.check()

    def read(self, offset: int, size: int, now: int) -> int:
        word = offset & ~3
        if word not in self.regs:
            self.word(offset, "read")  # raises naming the register
        value = int(self._lib.hil_tim1_load(self._p, word >> 2, now))
        self._cb.check()
        return lane(value, offset, size)

    def load(self, word: int, now: int) -> int:
        value = int(self._lib.hil_tim1_load(self._p, word >> 2, now))
        self._cb.check()
        return value

    def store(self, word: int, value: int, now: int) -> None:
        status = self._lib.hil_tim1_store(self._p, word >> 2, value & 0xFFFF_FFFF, now)
        self._cb.check()
        if status:
            raise BoardError(_ERRORS[status])

    def subscribe(self, signal: str, listener: Listener) -> None:
        if signal not in SIGNALS:
            raise BoardError(f"TIM1 has no trigger signal {signal!r}")
        fn, user = self._c_listener(listener)
        if self._lib.hil_tim1_subscribe(self._p, SIGNALS.index(signal), fn, user) != 0:
            raise BoardError(f"TIM1: too many listeners of {signal}")

    def unsubscribe(self, listener: Listener) -> None:
        fn, user = self._c_listener(listener)
        self._lib.hil_tim1_unsubscribe(self._p, fn, user)

    def _c_listener(self, listener: Any) -> tuple[int, int | None]:
        """(function, user) of a listener: a model in C gives its own (`c_listener`), a Python callable is
        wrapped (once) as a C callback."""
        native = getattr(getattr(listener, "__self__", None), "c_listener", None)
        if native is not None:
            fn, user = native()
            self._py_listeners[(fn, user)] = listener
            return fn, user
        for (fn, user), known in self._py_listeners.items():
            if known == listener:
                return fn, user

        def call(_user: int, signal: int, rising: int, at: int) -> None:
            listener(SIGNALS[signal], bool(rising), at)

        c_fn = self._cb.keep(pn.LISTENER_FN(self._cb.guard(call)))
        fn_address = pn.address(c_fn)
        self._py_listeners[(fn_address, None)] = listener
        return fn_address, None

    # --- for a scheduler in C --------------------------------------------------------------------------------------

    def c_ops(self) -> int:
        """Address of the model's hil_periph_ops_t (c/periph_ops.h): next_event / advance without Python."""
        return self._p + pn.Tim1State.ops.offset

    @property
    def native_ops(self) -> PeriphOps:
        """The model's hil_periph_ops_t as the board's C core holds it (called without Python)."""
        return PeriphOps.from_address(self.c_ops())

    def set_irq_sink(self, board: int, assert_line: int, withdraw_line: int, touched: int = 0) -> None:
        """Raise the interrupt lines through C functions (an NVIC in C: periph_native.set_sink); `touched`: the
        scheduler in C that hears of the accesses the library's MMIO callbacks serve."""
        pn.set_sink(self._s.sink, board, assert_line, withdraw_line, touched)

    def raise_held(self) -> None:
        """Raise what a Python listener raised while the C core called the model directly."""
        self._cb.check()

    # --- the register page ---------------------------------------------------------------------------------------

    def map_native(self, cpu: Any, read: Any, write: Any) -> None:
        """Serve TIM1's page from the library (`read`/`write`: the board's decoder, for the rest) on `cpu`."""
        self._s.count = ctypes.addressof(cpu.counter) + CounterState.count.offset
        lib = self._lib
        self._keep = pn.map_page(cpu, self.native_page, 0x1000, read, write, pn.address(lib.hil_tim1_mmio_read),
                                 pn.address(lib.hil_tim1_mmio_write), self._s)
