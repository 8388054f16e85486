"""The NVIC's state (Armv7-M B3.4; STM32G4: 4 priority bits, PM0214): enable, pending, active (a stack, in the
order the exceptions were taken), priority and grouping, and the choice of the exception that preempts. System
exceptions are numbered as in the vector table (SysTick 15), interrupt lines from 16 on.

Interrupt lines are level-sensitive as on the chip: a peripheral asserts a line (`assert_line`, pending it)
and withdraws it when its flag or enable clears; a line still asserted when its handler returns is pending again.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from pmsm_hil.sim_target.stm32g4.core_native import NvicState

NMI, HARDFAULT, MEMMANAGE, BUSFAULT, USAGEFAULT, SVCALL, PENDSV, SYSTICK = 2, 3, 4, 5, 6, 11, 14, 15
EXCEPTION_NAMES = {2: "NMI", 3: "HardFault", 4: "MemManage", 5: "BusFault", 6: "UsageFault", 11: "SVCall",
                   12: "DebugMonitor", 14: "PendSV", 15: "SysTick"}
#: implemented priority bits (__NVIC_PRIO_BITS = 4): the upper nibble of each 8-bit field
PRIO_MASK = 0xF0
#: execution priority with nothing active (above every configurable priority)
BASE_PRIORITY = 0x100


class Flags:
    """A set of exception numbers kept as one byte per exception in a C array (the core's state, c/board_core.c)."""

    def __init__(self, array: Any, size: int) -> None:
        self._a, self._size = array, size
        self._none = bytes(len(array))

    def add(self, exc: int) -> None:
        if 0 <= exc < self._size:  # an exception the part does not have (STIR beyond its lines): ignored
            self._a[exc] = 1

    def discard(self, exc: int) -> None:
        if 0 <= exc < self._size:
            self._a[exc] = 0

    def __contains__(self, exc: object) -> bool:
        return isinstance(exc, int) and 0 <= exc < self._size and bool(self._a[exc])

    def __iter__(self) -> Iterator[int]:
        raw = bytes(self._a)
        found, i = [], raw.find(1)
        while i >= 0:
            found.append(i)
            i = raw.find(1, i + 1)
        return iter(found)

    def __bool__(self) -> bool:
        return bytes(self._a) != self._none  # entries past `size` are never set

    def __len__(self) -> int:
        return sum(1 for v in bytes(self._a)[:self._size] if v)


class Stack:
    """The active exceptions in the order taken, kept in a C array and its length (the core's state)."""

    def __init__(self, state: NvicState) -> None:
        self._s = state

    def __len__(self) -> int:
        return int(self._s.n_active)

    def __bool__(self) -> bool:
        return bool(self._s.n_active > 0)

    def __getitem__(self, index: int) -> int:
        return int(list(self)[index])

    def __iter__(self) -> Iterator[int]:
        return iter(self._s.active[:self._s.n_active])

    def __contains__(self, exc: object) -> bool:
        return exc in list(self)

    def __eq__(self, other: object) -> bool:
        return list(self) == other

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return repr(list(self))

    def append(self, exc: int) -> None:
        n = self._s.n_active
        if n >= len(self._s.active):
            raise OverflowError(f"more than {n} exceptions active")
        self._s.active[n] = exc
        self._s.n_active = n + 1

    def remove(self, exc: int) -> None:
        items = list(self)
        items.remove(exc)
        self._s.active[:len(items)] = items
        self._s.n_active = len(items)


class Nvic:
    """Exception state of the core: `irq_count` interrupt lines after the 16 system exceptions. The state is `state`
    (the C core's hil_nvic_t: the Python scheduler and the C one see the same)."""

    def __init__(self, irq_count: int, state: NvicState | None = None) -> None:
        self.irq_count = irq_count
        self.size = 16 + irq_count
        self.state = state if state is not None else NvicState()
        if self.size > len(self.state.enabled):
            raise ValueError(f"{irq_count} interrupt lines: the core holds {len(self.state.enabled) - 16}")
        self.state.size = self.size
        self.enabled = self.state.enabled
        self.priority = self.state.priority
        self.pending = Flags(self.state.pending, self.size)
        self.active = Stack(self.state)
        self.asserted = Flags(self.state.asserted, self.size)
        for exc in (SVCALL, PENDSV, SYSTICK):
            self.enabled[exc] = 1  # system exceptions need no enable (SysTick is gated by its TICKINT)

    @property
    def prigroup(self) -> int:
        return int(self.state.prigroup)

    @prigroup.setter
    def prigroup(self, value: int) -> None:
        self.state.prigroup = value

    def group_priority(self, exc: int) -> int:
        """The group (preemption) priority of exception `exc`: -3..-1 for the fixed ones."""
        if exc == NMI:
            return -2
        if exc == HARDFAULT:
            return -1
        return int(self.priority[exc]) & ((0xFF << (self.prigroup + 1)) & 0xFF)

    def execution_priority(self, primask: bool, basepri: int) -> int:
        """The current execution priority: the highest (lowest value) of the active exceptions' group
        priorities, PRIMASK (0) and BASEPRI."""
        prio = min((self.group_priority(e) for e in self.active), default=BASE_PRIORITY)
        if basepri & PRIO_MASK:
            prio = min(prio, basepri & PRIO_MASK & ((0xFF << (self.prigroup + 1)) & 0xFF))
        if primask:
            prio = min(prio, 0)
        return prio

    def best_pending(self) -> int | None:
        """The pending, enabled exception that is taken first (lowest priority value, then lowest number)."""
        best, best_key = None, None
        for exc in self.pending:
            if not self.enabled[exc]:
                continue
            key = (self.group_priority(exc), self.priority[exc] if exc > HARDFAULT else 0, exc)
            if best_key is None or key < best_key:
                best, best_key = exc, key
        return best

    def preempting(self, primask: bool, basepri: int) -> int | None:
        """The exception to take now, None when nothing pending can preempt the current execution priority."""
        exc = self.best_pending()
        if exc is None:
            return None
        return exc if self.group_priority(exc) < self.execution_priority(primask, basepri) else None

    def masked_pending(self) -> bool:
        """Something enabled is pending but held off (by PRIMASK/BASEPRI or a running handler)."""
        return any(self.enabled[e] for e in self.pending)

    # --- lines --------------------------------------------------------------------------------------------------

    def assert_line(self, irq: int) -> None:
        exc = 16 + irq
        self.asserted.add(exc)
        if exc not in self.active:
            self.pending.add(exc)

    def withdraw_line(self, irq: int) -> None:
        exc = 16 + irq
        self.asserted.discard(exc)
        self.pending.discard(exc)

    def taken(self, exc: int) -> None:
        """Exception `exc` entered: active, no longer pending."""
        self.pending.discard(exc)
        self.active.append(exc)

    def returned(self, exc: int) -> None:
        """Exception `exc` returned; a line still asserted pends again."""
        self.active.remove(exc)
        if exc in self.asserted:
            self.pending.add(exc)

    # --- NVIC registers (0xE000E100..0xE000E4EF) -----------------------------------------------------------------

    def read(self, offset: int, size: int) -> int | None:
        """Value of the NVIC register at `offset` from 0xE000E000, None when `offset` is no NVIC register."""
        if 0x400 <= offset < 0x400 + self.irq_count:
            first = 16 + offset - 0x400
            return int.from_bytes(bytes(self.priority[first + i] if first + i < self.size else 0
                                        for i in range(size)), "little")
        if 0x100 <= offset < 0x320 and offset & 0x7F < 0x20:
            group, word = (offset - 0x100) >> 7, (offset & 0x7F) >> 2
            bits = 0
            for bit in range(32):
                exc = 16 + 32 * word + bit
                if exc >= self.size:
                    break
                if group <= 1:
                    on = bool(self.enabled[exc])
                elif group <= 3:
                    on = exc in self.pending
                else:
                    on = exc in self.active
                bits |= int(on) << bit
            return bits
        return None

    def write(self, offset: int, size: int, value: int) -> bool:
        """Store into the NVIC register at `offset`; False when `offset` is no writable NVIC register."""
        if 0x400 <= offset < 0x400 + self.irq_count:
            for i in range(size):
                exc = 16 + offset - 0x400 + i
                if exc < self.size:
                    self.priority[exc] = (value >> (8 * i)) & PRIO_MASK
            return True
        if 0x100 <= offset < 0x300 and offset & 0x7F < 0x20:
            group, word = (offset - 0x100) >> 7, (offset & 0x7F) >> 2
            for bit in range(32):
                if not value >> bit & 1:
                    continue
                exc = 16 + 32 * word + bit
                if exc >= self.size:
                    break
                if group == 0:
                    self.enabled[exc] = 1
                elif group == 1:
                    self.enabled[exc] = 0
                elif group == 2:
                    self.pending.add(exc)
                else:
                    self.pending.discard(exc)
            return True
        return False


class AssertTimes:
    """The cycle each exception's line (or SysTick) asked, until the exception is entered (its latency's start): a
    mapping kept in the core's C arrays (has_assert, assert_at)."""

    def __init__(self, state: NvicState) -> None:
        self._s = state

    def __contains__(self, exc: object) -> bool:
        return isinstance(exc, int) and bool(self._s.has_assert[exc])

    def __setitem__(self, exc: int, at: int) -> None:
        self._s.assert_at[exc] = at
        self._s.has_assert[exc] = 1

    def pop(self, exc: int, default: int | None = None) -> int | None:
        if not self._s.has_assert[exc]:
            return default
        self._s.has_assert[exc] = 0
        return int(self._s.assert_at[exc])

    def setdefault(self, exc: int, at: int) -> int:
        if not self._s.has_assert[exc]:
            self[exc] = at
        return int(self._s.assert_at[exc])
