"""The CORDIC co-processor of the STM32G474 (RM0440 "CORDIC co-processor") at 0x40020C00: CSR, WDATA, RDATA, the
CORDIC interrupt (IRQ 100).

The functions (FUNC) are those of RM0440 with its argument and result scaling: cosine, sine, phase, modulus,
arctangent, hyperbolic cosine, hyperbolic sine, hyperbolic arctangent, natural logarithm, square root, in q1.31
(one 32-bit word per argument or result) or q1.15 (both in one word, the first in the low half). The model runs the
CORDIC iterations themselves, 4 per PRECISION step, in double precision (circular rotation or vectoring for the
first five, hyperbolic with the repeated steps 4, 13, 40 for the others), so its error falls by about one bit per
iteration as the chip's does; the chip's own fixed-point rounding (below 2^-31) is not reproduced. The results are
ready PRECISION cycles after the last argument (4 iterations a cycle); a read of RDATA before then stalls the bus
on the chip and returns the result here at once. DMA requests (DMAREN, DMAWEN) are not modelled.
"""

from __future__ import annotations

import math

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, Peripheral, register

CSR, WDATA, RDATA = 0x0, 0x4, 0x8
IRQ = 100

# CSR fields
FUNC_MASK, PRECISION_SHIFT, SCALE_SHIFT = 0xF, 4, 8
IEN, DMAREN, DMAWEN = 1 << 16, 1 << 17, 1 << 18
NRES, NARGS, RESSIZE, ARGSIZE = 1 << 19, 1 << 20, 1 << 21, 1 << 22
RRDY = 1 << 31
CSR_WRITABLE = 0x007F_07FF
CSR_RESET = 0x0000_0050  # PRECISION 5, cosine

COS, SIN, PHASE, MODULUS, ATAN, COSH, SINH, ATANH, LN, SQRT = range(10)
FUNCTION_NAMES = ("cosine", "sine", "phase", "modulus", "arctangent", "hyperbolic cosine", "hyperbolic sine",
                  "hyperbolic arctangent", "natural logarithm", "square root")
#: the SCALE values RM0440 allows per function (the others have a fixed scale: 0, or 1 for the hyperbolic ones)
SCALES = {ATAN: range(8), LN: range(1, 5), SQRT: range(3)}
FIXED_SCALE = {COSH: 1, SINH: 1, ATANH: 1}

_CIRCULAR_STEPS = [math.atan(2.0 ** -i) for i in range(64)]


def _hyperbolic_schedule(count: int) -> list[int]:
    """The shift of each of `count` hyperbolic iterations: 1, 2, 3, 4, 4, 5, ..., 13, 13, ... (3k + 1 repeated)."""
    shifts: list[int] = []
    i, repeat = 1, 4
    while len(shifts) < count:
        shifts.append(i)
        if i == repeat and len(shifts) < count:
            shifts.append(i)
            repeat = 3 * repeat + 1
        i += 1
    return shifts


def circular_rotate(angle: float, iterations: int) -> tuple[float, float]:
    """(cos, sin) of `angle` [rad, |angle| <= pi] by `iterations` circular rotation steps."""
    flip = 1.0
    if angle > math.pi / 2:
        angle, flip = angle - math.pi, -1.0
    elif angle < -math.pi / 2:
        angle, flip = angle + math.pi, -1.0
    gain = math.prod(math.sqrt(1.0 + 4.0 ** -i) for i in range(iterations))
    x, y, z = 1.0 / gain, 0.0, angle
    for i in range(iterations):
        d = 1.0 if z >= 0 else -1.0
        x, y = x - d * y * 2.0 ** -i, y + d * x * 2.0 ** -i
        z -= d * _CIRCULAR_STEPS[i]
    return flip * x, flip * y


def circular_vector(x: float, y: float, iterations: int) -> tuple[float, float]:
    """(modulus, phase [rad]) of the vector (x, y) by `iterations` circular vectoring steps."""
    z = 0.0
    if x < 0:
        z = math.pi if y >= 0 else -math.pi
        x, y = -x, -y
    gain = math.prod(math.sqrt(1.0 + 4.0 ** -i) for i in range(iterations))
    for i in range(iterations):
        d = -1.0 if y >= 0 else 1.0
        x, y = x - d * y * 2.0 ** -i, y + d * x * 2.0 ** -i
        z -= d * _CIRCULAR_STEPS[i]
    if z > math.pi:
        z -= 2 * math.pi
    return x / gain, z


def hyperbolic_rotate(t: float, iterations: int) -> tuple[float, float]:
    """(cosh, sinh) of `t` by `iterations` hyperbolic rotation steps."""
    shifts = _hyperbolic_schedule(iterations)
    gain = math.prod(math.sqrt(1.0 - 4.0 ** -i) for i in shifts)
    x, y, z = 1.0 / gain, 0.0, t
    for i in shifts:
        d = 1.0 if z >= 0 else -1.0
        x, y = x + d * y * 2.0 ** -i, y + d * x * 2.0 ** -i
        z -= d * math.atanh(2.0 ** -i)
    return x, y


def hyperbolic_vector(x: float, y: float, iterations: int) -> tuple[float, float]:
    """(sqrt(x^2 - y^2), atanh(y / x)) by `iterations` hyperbolic vectoring steps (x > |y|)."""
    shifts = _hyperbolic_schedule(iterations)
    gain = math.prod(math.sqrt(1.0 - 4.0 ** -i) for i in shifts)
    z = 0.0
    for i in shifts:
        d = -1.0 if y >= 0 else 1.0
        x, y = x + d * y * 2.0 ** -i, y + d * x * 2.0 ** -i
        z -= d * math.atanh(2.0 ** -i)
    return x / gain, z


def evaluate(func: int, arg1: float, arg2: float, scale: int, iterations: int) -> tuple[float, float]:
    """(RES1, RES2) of function `func` as RM0440 scales them, from the arguments as q-format values."""
    if func in (COS, SIN):
        cos, sin = circular_rotate(arg1 * math.pi, iterations)
        return (arg2 * cos, arg2 * sin) if func == COS else (arg2 * sin, arg2 * cos)
    if func in (PHASE, MODULUS):
        modulus, phase = circular_vector(arg1, arg2, iterations)
        return (phase / math.pi, modulus) if func == PHASE else (modulus, phase / math.pi)
    if func == ATAN:
        _, phase = circular_vector(1.0, arg1 * 2.0 ** scale, iterations)
        return phase / math.pi * 2.0 ** -scale, 0.0
    if func in (COSH, SINH):
        cosh, sinh = hyperbolic_rotate(arg1 * 2.0, iterations)
        return (cosh / 2, sinh / 2) if func == COSH else (sinh / 2, cosh / 2)
    if func == ATANH:
        _, z = hyperbolic_vector(1.0, arg1 * 2.0, iterations)
        return z / 2, 0.0
    w = arg1 * 2.0 ** scale
    if func == LN:
        _, z = hyperbolic_vector(w + 1.0, w - 1.0, iterations)
        return 2.0 * z * 2.0 ** -(scale + 1), 0.0
    root, _ = hyperbolic_vector(w + 0.25, w - 0.25, iterations)
    return root * 2.0 ** -scale, 0.0


def to_q(value: float, bits: int) -> int:
    """`value` as a two's-complement q1.(bits - 1) word, rounded and saturated to [-1, 1)."""
    full = 1 << (bits - 1)
    q = max(-full, min(full - 1, round(value * full)))
    return q & ((1 << bits) - 1)


def from_q(word: int, bits: int) -> float:
    """The value of a two's-complement q1.(bits - 1) word."""
    word &= (1 << bits) - 1
    return (word - (1 << bits) if word >> (bits - 1) else word) / (1 << (bits - 1))


@register("CORDIC")
class Cordic(Peripheral):
    """The CORDIC co-processor: arguments in through WDATA, results out through RDATA."""

    base = 0x4002_0C00
    size = 0x400
    #: a computation's end is its only event
    EVENT_DRIVEN = True

    def reset(self) -> None:
        self.csr = CSR_RESET
        #: ARG2 keeps its last value between computations; +1 (0x7FFFFFFF) after reset
        self.arg2 = 0x7FFF_FFFF
        self._arg1: int | None = None
        self._results: list[int] = []
        self.ready_at: int | None = None
        self._signalled = False
        self._line_up = False
        #: computations started (count)
        self.computations = 0

    def read(self, offset: int, size: int, now: int) -> int:
        del size
        if offset == CSR:
            return self.csr | (RRDY if self._results and self._is_ready(now) else 0)
        if offset == WDATA:
            return 0
        if offset == RDATA:
            if not self._results:
                return 0
            value = self._results.pop(0)
            if not self._results:
                self._update_line()
            return value
        raise self._unknown(offset, "read")

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        del size
        if offset == CSR:
            if value & (DMAREN | DMAWEN):
                raise BoardError("CORDIC_CSR: DMA requests (DMAREN, DMAWEN) are not modelled by the virtual board")
            func = value & FUNC_MASK
            if func > SQRT:
                raise BoardError(f"CORDIC_CSR: FUNC = {func} is reserved (RM0440: 0 to 9)")
            self.csr = value & CSR_WRITABLE
            self._arg1 = None
            self._update_line()
        elif offset == WDATA:
            self._argument(value & 0xFFFF_FFFF, now)
        elif offset == RDATA:
            return  # read-only
        else:
            raise self._unknown(offset, "write")

    def _unknown(self, offset: int, access: str) -> BoardError:
        return BoardError(f"{access} of CORDIC at offset {offset:#05x} ({self.base + offset:#010x}), which the virtual "
                          "board does not model (CSR, WDATA, RDATA)")

    def _argument(self, word: int, now: int) -> None:
        """A WDATA write: the arguments complete with it start a computation."""
        if self.csr & ARGSIZE:  # q1.15: ARG1 in the low half, ARG2 in the high half, one write
            arg1, arg2 = from_q(word, 16), from_q(word >> 16, 16)
        elif self.csr & NARGS and self._arg1 is None:
            self._arg1 = word
            return
        elif self.csr & NARGS:
            assert self._arg1 is not None
            arg1, self.arg2 = from_q(self._arg1, 32), word
            arg2 = from_q(word, 32)
            self._arg1 = None
        else:
            arg1, arg2 = from_q(word, 32), from_q(self.arg2, 32)
        self._compute(arg1, arg2, now)

    def _compute(self, arg1: float, arg2: float, now: int) -> None:
        func = self.csr & FUNC_MASK
        precision = (self.csr >> PRECISION_SHIFT) & 0xF
        if precision == 0:
            raise BoardError("CORDIC_CSR: PRECISION = 0 is reserved (RM0440: 1 to 15 steps of 4 iterations)")
        scale = (self.csr >> SCALE_SHIFT) & 0x7
        allowed = SCALES.get(func)
        if allowed is not None and scale not in allowed:
            raise BoardError(f"CORDIC_CSR: SCALE = {scale} is outside {FUNCTION_NAMES[func]}'s range "
                             f"({allowed.start} to {allowed.stop - 1})")
        scale = FIXED_SCALE.get(func, scale) if allowed is None else scale
        res1, res2 = evaluate(func, arg1, arg2, scale, 4 * precision)
        if self.csr & RESSIZE:
            self._results = [to_q(res1, 16) | (to_q(res2, 16) << 16)]
        else:
            self._results = [to_q(res1, 32), to_q(res2, 32)][:2 if self.csr & NRES else 1]
        self.computations += 1
        self.ready_at = now + precision
        self._signalled = False
        self._update_line()

    def _is_ready(self, now: int) -> bool:
        return self.ready_at is not None and now >= self.ready_at

    def next_event(self, now: int) -> int | None:
        if self._results and not self._signalled and self.ready_at is not None:
            return max(self.ready_at, now + 1)
        return None

    def advance(self, now: int) -> None:
        if self._results and self._is_ready(now):
            self._signalled = True
            self._update_line()

    def _update_line(self) -> None:
        """The interrupt line: IEN and results ready (RRDY as the last `advance` saw it)."""
        up = bool(self.csr & IEN and self._results and self._signalled)
        if up and not self._line_up:
            self.bus.set_pending(IRQ)
        elif self._line_up and not up:
            self.bus.clear_pending(IRQ)
        self._line_up = up


__all__ = ["Cordic", "evaluate", "from_q", "to_q"]
