"""What the board link (link.py) shares with its common control period in C (c/board_period.c): the rotor's angle
and speed, the period's start and signal values, held in the C period's state (period_native.PeriodState), and the
per-period counters, which the C period leaves in a ring that is read into the lists here when Python reads them
(the C period runs without the GIL, maybe while another thread reads: the ring's `head` and the running sums are
its alone, `tail` and what was taken of the sums Python's). Either path — the Python reference or the period in C —
reads and writes the same values through these properties.
"""

from __future__ import annotations

from pmsm_hil.protocol.links.stats import LinkStats
from pmsm_hil.sim_target.stm32g4.period_native import RING, PeriodState, new_state


def _counts(name: str, doc: str) -> property:
    """A per-period counter list `name` of PeriodShared, read after the C period's ring (`_flush`)."""

    def get(self: PeriodShared) -> list[int]:
        self._flush()
        out: list[int] = getattr(self, name)
        return out

    return property(get, doc=doc)


class PeriodShared:
    """The board link's period state, in C (call `_init_shared` before anything else of the link)."""

    _ps: PeriodState

    def _init_shared(self) -> None:
        self._ps = new_state()
        self._isr_cycles: list[int] = []
        self._sleep_cycles: list[int] = []
        self._late_per_period: list[int] = []
        self._entries_per_period: list[int] = []
        self._stats = LinkStats()
        self._wall_s = 0.0
        #: the C period's frame count and wall time [ns] already added to `_stats` and `_wall_s`
        self._frames_taken = 0
        self._wall_taken = 0
        ps = self._ps
        #: (the C ring, its list) per counter, the ring as int64 memory (slices read in one call)
        self._rings = [(memoryview(ring).cast("B").cast("q"), out) for ring, out in (
            (ps.sleep, self._sleep_cycles), (ps.late, self._late_per_period), (ps.entries, self._entries_per_period),
            (ps.isr, self._isr_cycles))]

    def _flush(self) -> None:
        """The C period's counters so far into the lists (in period order)."""
        ps = self._ps
        head, tail = int(ps.head), int(ps.tail)
        if head == tail:
            return
        i, j = tail % RING, head % RING
        for ring, out in self._rings:  # `isr_cycles` last: a period counts as recorded once it has it
            if i < j:
                out.extend(ring[i:j].tolist())
            else:
                out.extend(ring[i:].tolist())
                out.extend(ring[:j].tolist())
        ps.tail = head

    # --- the per-period counters --------------------------------------------------------------------------------

    isr_cycles = _counts("_isr_cycles", "Per control period: cycles in interrupt handlers.")
    sleep_cycles = _counts("_sleep_cycles", "Per control period: cycles the core slept.")
    late_per_period = _counts("_late_per_period", "Per control period: late compare values (TIM1's count, 0 or 1).")
    entries_per_period = _counts("_entries_per_period", "Per control period: exception entries.")

    @property
    def late_first_period(self) -> int | None:
        """The first control period whose compare values landed late (None: none did)."""
        value = int(self._ps.late_first_period)
        return None if value < 0 else value

    @late_first_period.setter
    def late_first_period(self, value: int | None) -> None:
        self._ps.late_first_period = -1 if value is None else value

    @property
    def periods(self) -> int:
        """Control periods run."""
        return int(self._ps.periods)

    @periods.setter
    def periods(self, value: int) -> None:
        self._ps.periods = value

    @property
    def stats(self) -> LinkStats:
        """The link's frame counts (the Measurements the C period took included)."""
        n = int(self._ps.frames_tx)
        if n != self._frames_taken:
            self._stats.frames_tx += n - self._frames_taken
            self._frames_taken = n
        return self._stats

    @stats.setter
    def stats(self, value: LinkStats) -> None:
        self._stats = value

    @property
    def wall_s(self) -> float:
        """Wall time spent in the board's periods [s]."""
        n = int(self._ps.wall_ns)
        if n != self._wall_taken:
            self._wall_s += (n - self._wall_taken) * 1e-9
            self._wall_taken = n
        return self._wall_s

    @wall_s.setter
    def wall_s(self, value: float) -> None:
        self._wall_taken = int(self._ps.wall_ns)
        self._wall_s = value

    # --- the inputs -----------------------------------------------------------------------------------------------

    @property
    def _theta_m(self) -> float:
        """Unwrapped mechanical angle at the period start [rad]."""
        return float(self._ps.theta_m)

    @_theta_m.setter
    def _theta_m(self, value: float) -> None:
        self._ps.theta_m = value

    @property
    def _theta_e(self) -> float | None:
        """The last Measurement's electrical angle [rad] (None: none yet)."""
        ps = self._ps
        return float(ps.theta_e) if ps.has_theta_e else None

    @_theta_e.setter
    def _theta_e(self, value: float | None) -> None:
        ps = self._ps
        ps.has_theta_e = value is not None
        ps.theta_e = 0.0 if value is None else value

    @property
    def _omega_m(self) -> float:
        """Mechanical speed [rad/s]."""
        return float(self._ps.omega_m)

    @_omega_m.setter
    def _omega_m(self, value: float) -> None:
        self._ps.omega_m = value

    @property
    def _period_start(self) -> int:
        """The control period's first cycle."""
        return int(self._ps.period_start)

    @_period_start.setter
    def _period_start(self, value: int) -> None:
        self._ps.period_start = value

    @property
    def _stale_signals(self) -> tuple[float, float, float, float] | None:
        """The period's signal values (SIGNALS' order) while the pin voltages in Python have not been brought up to
        them (the table took them in C); None: they are current."""
        ps = self._ps
        if not ps.stale:
            return None
        a, b, c, d = ps.signals
        return (a, b, c, d)

    @_stale_signals.setter
    def _stale_signals(self, value: tuple[float, float, float, float] | None) -> None:
        ps = self._ps
        ps.stale = value is not None
        if value is not None:
            ps.signals[:] = value
