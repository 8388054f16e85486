"""The virtual board as the run's target (`--target stm32g4:FW.elf`): the host's end of the link is this object.
`send` takes the host's frames; a Measurement runs one control period on the board and queues the reply that
`poll`/`recv` return. The native loop's C link (src/pmsm_hil/hil/runner/c/links/link_board.c) runs the same period
through `measurement` with the decoded values and encodes the duty-cycle Command itself.

Per period k (lockstep): the Measurement's phase currents and DC-link voltage become the voltages at the ADC pins
through the board's analog front end (constant over the period: the host sampled them at its --adc-delay) and, when
the board describes an overcurrent protection on TIM1's BKIN pin ([break_input]), that pin's level, its angle
and speed the encoder's edge count (the mechanical angle unwrapped from the electrical one, advanced at the measured
speed inside the period; the encoder aligned: count 0 at electrical angle 0); the core runs to the end of the period
(the next update event of TIM1 at the carrier valley); the reply is a duty-cycle Command built from the compare
values in force for the next period (PWM mode and polarity per channel), shortened or lengthened by BDTR's dead time
according to each phase current's sign (the average effect of the dead time; the plant's own dead-time parameter is
not used), with the core's cycles in interrupt handlers during the period as exec_time_ns.

The host's period must be the firmware's carrier period: the board runs the firmware's start-up until TIM1
counts, and refuses a different --ts naming both. ConfigParams are acknowledged by the board on the firmware's
behalf while the firmware has not taken FDCAN1 out of initialisation (CCCR.INIT never cleared: it has no bus then;
enabling Setpoints are counted and dropped, a disabling one trips TIM1's break input as a gate driver's enable line
would, and the board confirms it); once it has, the frames go to its FDCAN1 model and its own answers come back
(python-can Messages on the model's side), one after the other at the end of their bus time at the firmware's bit
rates; a frame that arrives outside a control period (configuration, the safe stop) is answered in idle periods of
the firmware with the last inputs held (at most IDLE_PERIODS per frame). A Measurement does not wait for the bus:
host frames still on it are received at the start of its period.
"""

from __future__ import annotations

import ctypes
import math
import random
import time
from collections import deque
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import can
import numpy as np

from pmsm_hil.protocol.codec import FrameCodec, FrameDecoder
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.ids import NodeState, Status
from pmsm_hil.protocol.messages import Command, ConfigAck, ConfigParam, Heartbeat, Measurement, Setpoint
from pmsm_hil.sim_target.qemu import stats
from pmsm_hil.sim_target.stm32g4 import core_native, period_native
from pmsm_hil.sim_target.stm32g4 import periph_native as pn
from pmsm_hil.sim_target.stm32g4.board import VREFINT_V
from pmsm_hil.sim_target.stm32g4.board_file import SIGNALS, BoardDescription
from pmsm_hil.sim_target.stm32g4.counter import CounterState
from pmsm_hil.sim_target.stm32g4.hall import HallSensors, attach_halls
from pmsm_hil.sim_target.stm32g4.link_base import IDLE_PERIODS, STARTUP_LIMIT_S, BoardLinkBase
from pmsm_hil.sim_target.stm32g4.link_shared import PeriodShared
from pmsm_hil.sim_target.stm32g4.peripherals.adc_native import FRONT_MAX, Adc12Pair, NativeAdc, pair_of
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.fdcan import INIT as FDCAN_INIT
from pmsm_hil.sim_target.stm32g4.peripherals.fdcan import Fdcan
from pmsm_hil.sim_target.stm32g4.peripherals.opamp import ADC_CHANNELS as OPAMP_CHANNELS
from pmsm_hil.sim_target.stm32g4.peripherals.opamp import OPAINTOEN, Opamp
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import BDTR as TIM1_BDTR
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import CCER as TIM1_CCER
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import CR2 as TIM1_CR2
from pmsm_hil.sim_target.stm32g4.peripherals.tim1 import Tim1
from pmsm_hil.sim_target.stm32g4.peripherals.tim1_native import NativeTim1
from pmsm_hil.sim_target.stm32g4.peripherals.tim_gp import GeneralTimer

#: carrier period mismatch tolerated between the firmware and --ts [s]
PERIOD_TOLERANCE_S = 1e-9
#: the ADCs whose conversions can take their codes from a table (c/adc.c), and its channels per ADC
PAIR = ("ADC1", "ADC2")
TABLE_CHANNELS = 32


class BoardLink(PeriodShared, BoardLinkBase):
    """The host's link to a firmware running on the virtual board (implements the Link protocol)."""

    #: the common control period in C (c/board_period.c: the inputs, the core's run and the counters of a
    #: Measurement's period without Python, which it hands back for the rare legs; False: the Python reference,
    #: which gives the same records: tests/board/test_native_exc.py)
    NATIVE_PERIOD = True

    def __init__(self, elf: str | Path, desc: BoardDescription, *, ts_s: float, pole_pairs: int,
                 skip_periods: int = 0, console: Any = None, psi_f_wb: float = 0.0, vdc_v: float = 0.0,
                 can_bitrates: tuple[int | None, int | None] = (None, None)) -> None:
        self._init_shared()
        super().__init__(elf, desc, skip_periods=skip_periods, console=console)
        self._tim1 = self.tim1
        #: TIM1 when it is the model in C (its counters read from `native_state`), else None
        self._tim1_c = self._tim1 if isinstance(self._tim1, NativeTim1) else None
        self.pole_pairs = pole_pairs
        self.codec = FrameCodec("canfd")
        self.decoder = FrameDecoder(ordered=False)
        self._rng = random.Random(0x5EED)
        #: the machine's magnet flux [Wb]: the open bridge's phase voltages are its back EMF (MOE = 0)
        self.psi_f_wb = psi_f_wb
        #: the machine's nominal DC-link voltage [V] (the open bridge before the first Measurement)
        self.vdc_v = vdc_v
        #: the run's period [ns] (the full-period switching state of driven idle levels)
        self.ts_ns = round(ts_s * 1e9)
        #: the seq of the last Command sent with every gate off (outputs_off)
        self._off_seq: int | None = None
        # before the first Measurement: no phase current, the DC link at its nominal voltage
        zero = {"i_a": 0.0, "i_b": 0.0, "i_c": 0.0, "vdc": vdc_v}
        self._volts: dict[tuple[str, int], float] = {(a.adc, a.channel): a.offset_v + a.gain * zero[a.signal]
                                                     for a in desc.analog}
        self._noise = {(a.adc, a.channel): a.noise_v for a in desc.analog}
        #: per analog input: ((adc, channel), offset [V], gain [V per unit], its signal's index in SIGNALS)
        self._analog_map = [((a.adc, a.channel), a.offset_v, a.gain, SIGNALS.index(a.signal)) for a in desc.analog]
        self.board.analog = self._analog
        #: the ADC pair in C behind a noiseless front end of its own pins: their voltages go into the pair's table
        #: once a period (no call into Python per conversion); None: each conversion asks `_analog`
        self._adc_table = self._table_pair(desc)
        #: the period's signal values (SIGNALS' order) while `_volts` has not been brought up to them (the table
        #: took them in C); None: `_volts` is current
        self._stale_signals: tuple[float, float, float, float] | None = None
        #: the period's table was filled by the caller in C (`measurement(native=True)`, `native_io`)
        self._table_in_c = False
        #: a caller in C computes TIM1's compare duties (`native_io` gave it the function)
        self._duties_in_c = False
        opamp = self.board.peripherals.get("OPAMP")
        #: the amplifiers whose outputs can be routed to ADC1 or ADC2 (the table is off while one is)
        self._pair_opamps = (opamp, sorted({number - 1 for (adc, _), number in OPAMP_CHANNELS.items() if adc in PAIR})
                             ) if isinstance(opamp, Opamp) else None
        if self._adc_table is not None:
            self._adc_table.set_front_end([(a, ch, off, gain, sig) for (a, ch), off, gain, sig in self._analog_map],
                                          len(SIGNALS), desc.vref_v, VREFINT_V)
        self.board.encoder = self._encoder
        self.hclk_hz = self.board.hclk_hz
        timer = self.board.peripherals.get(desc.encoder_timer or "")
        #: the encoder timer whose CNT reads are answered in C from `_encoder`'s values (`_sync_encoder`), or None
        self._c_encoder = timer if isinstance(timer, GeneralTimer) and timer.arm_encoder(desc.encoder_lines) else None
        self._sync_encoder()
        #: the C read's encoder struct, set field by field once a period (the angle and speed before it, its start
        #: after it: `_sync_encoder` at every other change), or None
        self._encoder_state = self._c_encoder.encoder_state() if self._c_encoder is not None else None
        #: the C core's counters, read directly once a period (Board.LAZY_STATS), or None: through the board
        self._core_counts = self.board._core if self.board._lazy_stats else None
        #: the hall sensors of the board description on their GPIO pins (None: the board has none)
        self.halls: HallSensors | None = None
        #: the electrical angle the hall sensors hold in idle periods (the plant does not advance then) [rad]
        self._hall_held: float | None = None
        if desc.hall is not None:
            self.halls = attach_halls(self.board, desc.hall, self._trajectory)
        self.setpoints_dropped = 0
        self._heartbeats = 0
        #: host frames on the firmware's bus: (cycle at which FDCAN1 has received it, frame), in bus order
        self._on_bus: deque[tuple[int, can.Message]] = deque()
        self._bus_free = 0  # the cycle at which the last host frame leaves the bus
        self._last_arrival = 0  # the cycle at which FDCAN1 received the last host frame
        #: idle periods the firmware may still get to finish sending its answer to host frames a Measurement
        #: period delivered (while FDCAN1 has a transmission requested or on the bus)
        self._answer_left = 0
        self.configs_acked = 0
        fdcan = self.board.peripherals.get("FDCAN1")
        self.fdcan = fdcan if isinstance(fdcan, Fdcan) else None
        if desc.break_overcurrent_a is not None:  # BKIN at its idle level: no overcurrent
            self.tim1.set_break_pin(desc.break_active_low, 0)
        if self.fdcan is not None:  # checked against the firmware's bit timing when it joins the bus
            self.fdcan.link_bitrates = can_bitrates
        self._bus_on = False
        #: why the firmware stopped the board before TIM1 counted (a fault, an access the board does not model, a
        #: start-up that never starts TIM1): raised at the first Measurement, so that the run ends as a safety stop
        #: with its outputs written (the reason one line), not as a usage error
        self.boot_error = None
        self.carrier_s = ts_s
        self.period_cycles = round(ts_s * self.hclk_hz)
        try:
            self._boot()
        except BoardError as exc:
            self.boot_error = exc
            return
        self._start(ts_s)
        self._setup_period()

    # --- start-up and period --------------------------------------------------------------------------------------

    @property
    def tim1(self) -> Tim1:
        timer = self.board.peripherals["TIM1"]
        assert isinstance(timer, Tim1)
        return timer

    def _boot(self) -> None:
        """Run the firmware's start-up until TIM1 counts and an update has passed."""
        tim = self.tim1
        self._run_startup(lambda: tim.running and tim.updates != 0,
                          lambda: f"stm32g4 target: TIM1 did not start within {STARTUP_LIMIT_S:g} s of the firmware's "
                                  f"start-up (at {self.board.describe_pc()})")

    def _start(self, ts_s: float) -> None:
        """After the start-up: check the carrier period against the host's (a mismatch is the run's usage error)
        and align the period start to an update at the carrier valley."""
        board, tim = self.board, self.tim1
        hz = board.hclk_hz
        carrier_s = tim.carrier_cycles() / hz
        mode = f"centre-aligned (CMS {tim.cms})" if tim.cms else "edge-aligned"
        setup = f"TIM1 ARR {tim.arr}, PSC {tim.psc}, {mode} at {hz / 1e6:g} MHz"
        if tim.update_period_cycles() != tim.carrier_cycles():
            raise BoardError(f"stm32g4 target: {setup} updates every {tim.update_period_cycles() / hz * 1e6:g} µs, "
                             f"not once per carrier period ({carrier_s * 1e6:g} µs): set RCR so that the compare "
                             "values load once per period (centre-aligned: RCR 1)")
        if abs(carrier_s - ts_s) > PERIOD_TOLERANCE_S:
            raise BoardError(f"stm32g4 target: the firmware's carrier period is {carrier_s * 1e6:.6g} µs ({setup}), "
                             f"the run's period --ts is {ts_s * 1e6:.6g} µs: run with --ts {carrier_s:.9g}")
        self.period_cycles = tim.carrier_cycles()
        # align to an update at the valley (counting up after it)
        while tim.cms and tim.seg_dir < 0:
            board.run_until(tim.last_update + tim.update_period_cycles())
        board.run_until(tim.last_update + self.period_cycles)
        self._period_start = tim.last_update
        self.carrier_s = carrier_s
        self.hclk_hz = hz
        self._sync_encoder()

    def _analog(self, adc: str, channel: int, now: int) -> float:
        if channel < 0:
            return self.desc.vref_v
        if self._stale_signals is not None:
            self._update_volts(*self._stale_signals)
        volts = self._volts.get((adc, channel))
        if volts is None:
            if adc.startswith("OPAMP"):
                raise BoardError(f"the firmware converts an internal amplifier's input {adc}, which board "
                                 f"{self.desc.name} does not describe (an [[analog]] entry with adc = {adc!r})")
            volts = 0.0
        noise = self._noise.get((adc, channel), 0.0)
        return volts + self._rng.gauss(0.0, noise) if noise else volts

    def _table_pair(self, desc: BoardDescription) -> Adc12Pair | None:
        """The ADC pair whose codes can come from a table of pin voltages (the models in C, every analog input an
        ADC1/ADC2 pin without noise), else None."""
        adc1 = self.board.peripherals.get("ADC1")
        if not isinstance(adc1, NativeAdc) or len(desc.analog) > FRONT_MAX or any(
                a.noise_v or a.adc not in ("ADC1", "ADC2") or not 0 <= a.channel < TABLE_CHANNELS
                for a in desc.analog):
            return None
        return pair_of(self.board)

    def _fill_table(self, pair: Adc12Pair, i_a: float, i_b: float, i_c: float, vdc: float) -> None:
        """The period's pin voltages, VREF+ and VREFINT (ADC1 IN18) into the pair's table (in C); while an
        amplifier's output is routed to ADC1 or ADC2 the conversions ask `_analog` (and the OPAMP model) instead."""
        opamps = self._pair_opamps
        if opamps is not None:
            opamp, numbers = opamps
            csr = opamp.csr
            for k in numbers:
                if csr[k] & OPAINTOEN:
                    self._update_volts(i_a, i_b, i_c, vdc)
                    pair.clear_inputs()
                    return
        if not self._table_in_c:
            pair.take((i_a, i_b, i_c, vdc))
        ps = self._ps  # `_stale_signals` (link_shared.py)
        signals = ps.signals
        signals[0], signals[1], signals[2], signals[3], ps.stale = i_a, i_b, i_c, vdc, 1

    def _update_volts(self, i_a: float, i_b: float, i_c: float, vdc: float) -> None:
        """Each analog input's pin voltage for the signal values [A, V] into `_volts`."""
        self._stale_signals = None
        volts = self._volts
        for key, offset, gain, signal in self._analog_map:
            volts[key] = offset + gain * (i_a if signal == 0 else i_b if signal == 1 else i_c if signal == 2 else vdc)

    def _encoder(self, timer: str, now: int) -> int:
        if timer != self.desc.encoder_timer:
            return 0
        dt = (now - self._period_start) / self.hclk_hz
        theta = self._theta_m + self._omega_m * dt
        return math.floor(theta / (2 * math.pi) * 4 * self.desc.encoder_lines)

    def _sync_encoder(self) -> None:
        """`_encoder`'s values into the encoder timer's C read (when it has one)."""
        timer = self._c_encoder
        if timer is not None:
            timer.sync_encoder(self._theta_m, self._omega_m, self._period_start, self.hclk_hz)

    def _trajectory(self, now: int) -> tuple[float, float]:
        """The rotor's electrical angle at cycle `now` [rad] (unwrapped, advanced at the measured speed inside the
        period, as the encoder's) and its electrical speed [rad per cycle]."""
        if self._hall_held is not None:
            return self._hall_held, 0.0
        rate = self.pole_pairs * self._omega_m / self.hclk_hz
        return self.pole_pairs * self._theta_m + rate * (now - self._period_start), rate

    def _take(self, i_a: float, i_b: float, i_c: float, theta_e: float, omega_m: float, vdc: float) -> None:
        """A Measurement's values [A, rad, rad/s, V] as the board's inputs for the period."""
        self._hall_held = None
        if self._adc_table is not None:
            self._fill_table(self._adc_table, i_a, i_b, i_c, vdc)
        else:
            self._update_volts(i_a, i_b, i_c, vdc)
        ps = self._ps  # `_theta_e`, `_theta_m`, `_omega_m` (link_shared.py), without the properties' calls
        if ps.has_theta_e:
            d = (theta_e - ps.theta_e + math.pi) % (2 * math.pi) - math.pi
            ps.theta_m += d / self.pole_pairs
        else:  # an aligned encoder: its zero where the electrical angle is zero
            ps.theta_m = theta_e / self.pole_pairs
        ps.theta_e, ps.has_theta_e = theta_e, 1
        ps.omega_m = omega_m
        state = self._encoder_state
        if state is not None:  # the period's start and the clock are those of the last `_sync_encoder`
            state.theta_m, state.omega_m = ps.theta_m, omega_m
        else:
            self._sync_encoder()
        limit = self.desc.break_overcurrent_a
        if limit is not None:  # the board's overcurrent comparator on BKIN, judged on the period's sample
            over = max(abs(i_a), abs(i_b), abs(i_c)) > limit
            self._tim1.set_break_pin(over != self.desc.break_active_low, self.board.now)

    def _period(self, i_a: float, i_b: float, i_c: float, theta_e: float, omega_m: float, vdc: float) -> int:
        """One control period of the firmware for a Measurement's values; the cycles it spent in interrupt handlers
        as exec_time_ns."""
        board = self.board
        self._take(i_a, i_b, i_c, theta_e, omega_m, vdc)
        snapshot = self._snapshot()
        start = self._ps.period_start  # `_period_start`
        end = start + self.period_cycles
        if self._on_bus:
            self._deliver_queued()
            self._run_to(end)
        else:  # as _deliver_queued and _run_to with no host frame on the bus
            if self._bus_free > start:  # (the board is at the period's start or past it)
                now = board.now
                if self._bus_free > now:
                    self._bus_free = now
            board.run_until(end)
        return self._period_end(end, snapshot)

    def _snapshot(self) -> tuple[int, int, int, int]:
        """The counters a period's records are differences of: (sleep, handler cycles, exception entries, TIM1's
        late compare values)."""
        core, board, tim_c = self._core_counts, self.board, self._tim1_c
        late0 = tim_c.native_state.late_writes if tim_c is not None else self._tim1.late_writes
        if core is not None:  # the C core's counters, read directly
            return core.sleep_cycles, core.handler_cycles, core.exc_entries, late0
        return board.sleep_cycles, board.handler_cycles, board.exception_entries, late0

    def _period_end(self, end: int, snapshot: tuple[int, int, int, int]) -> int:
        """After the core ran a period to cycle `end`: its records from `snapshot` (`_snapshot` at its start); the
        cycles it spent in interrupt handlers as exec_time_ns."""
        board, tim, core, tim_c = self.board, self._tim1, self._core_counts, self._tim1_c
        sleep0, isr0, entries0, late0 = snapshot
        self._flush()  # the C period's records first, then this one's (into the lists directly)
        ps = self._ps  # `_period_start`, `periods`, `late_first_period` (link_shared.py)
        ps.period_start = end
        state = self._encoder_state
        if state is not None:  # the angle, the speed and the clock as `_take` left them
            state.period_start = end
        isr: int
        entries: int
        if core is not None:
            isr = core.handler_cycles - isr0
            self._sleep_cycles.append(core.sleep_cycles - sleep0)
            entries = core.exc_entries - entries0
        else:
            isr = board.handler_cycles - isr0
            self._sleep_cycles.append(board.sleep_cycles - sleep0)
            entries = board.exception_entries - entries0
        if tim_c is not None:
            ts = tim_c.native_state  # again: a reset during the period gives the model a new struct
            self._late_per_period.append(ts.late_writes - late0)
            late_seen = ts.first_late_update >= 0
        else:
            self._late_per_period.append(tim.late_writes - late0)
            late_seen = tim.first_late_update is not None
        self._entries_per_period.append(entries)
        self._isr_cycles.append(isr)  # last: a period counts as recorded once this list has it (period_records)
        if ps.late_first_period < 0 and late_seen:
            ps.late_first_period = ps.periods
        ps.periods += 1
        return round(isr / self.hclk_hz * 1e9)

    # --- the period in C (c/board_period.c) -----------------------------------------------------------------------

    def _setup_period(self) -> None:
        """Hand the period in C what it reads and calls (the board's core, TIM1, the encoder's C read, the models'
        held errors), when every model of the common period is in C (NATIVE_PERIOD; else it stays off)."""
        ps, board, tim = self._ps, self.board, self._tim1_c
        core = self._core_counts
        if not (self.NATIVE_PERIOD and core is not None and tim is not None and self._adc_table is not None
                and self.halls is None):
            return
        period_native.library()  # built (and its size checked) before the state is used
        at = ctypes.addressof(core)
        ps.core, ps.run = at, core_native.address(board._core_lib.hil_core_run)
        ps.count = ctypes.addressof(board.cpu.counter) + CounterState.count.offset
        ps.sleep_cycles = at + core_native.CoreState.sleep_cycles.offset
        ps.handler_cycles = at + core_native.CoreState.handler_cycles.offset
        ps.exc_entries = at + core_native.CoreState.exc_entries.offset
        ts = ctypes.addressof(tim.native_state)
        ps.tim, ps.set_break_pin = ts, pn.address(pn.library("tim1").hil_tim1_set_break_pin)
        ps.late_writes = ts + pn.Tim1State.late_writes.offset
        ps.first_late_update = ts + pn.Tim1State.first_late_update.offset
        ps.bdtr = ts + pn.Tim1State.regs.offset + TIM1_BDTR
        enc = self._encoder_state
        if enc is not None:
            e = ctypes.addressof(enc)
            fields = type(enc)
            ps.enc_theta_m, ps.enc_omega_m = e + fields.theta_m.offset, e + fields.omega_m.offset
            ps.enc_period_start = e + fields.period_start.offset
        adcs = [p for p in board.peripherals.values() if isinstance(p, NativeAdc)]
        if len(adcs) > period_native.HELD_MAX:
            return
        for k, adc in enumerate(adcs):
            ps.held[k] = ctypes.addressof(adc._a) + type(adc._a).error.offset
        ps.n_held = len(adcs)
        ps.py_held = ctypes.addressof(pn.HELD)
        ps.pole_pairs, ps.hclk_hz, ps.period_cycles = self.pole_pairs, self.hclk_hz, self.period_cycles
        limit = self.desc.break_overcurrent_a
        ps.has_break, ps.break_limit_a = limit is not None, limit or 0.0
        ps.break_active_low = self.desc.break_active_low
        for model in (self.fdcan, self._pair_opamps[0] if self._pair_opamps is not None else None):
            if model is not None:
                model.on_change = self._wake
        #: `_period_c`'s arguments (the Measurement's values, its exec_time_ns)
        self._c_args = ((ctypes.c_double * 6)(), ctypes.c_int64())
        ps.enabled = 1
        self._sync_wake()

    def _wake(self) -> None:
        """Python takes the next period (and finishes the one running in C): something it handles changed."""
        self._ps.wake = 1

    def _sync_wake(self) -> None:
        """Whether the next period is Python's (frames to or from the host, FDCAN1 joining the bus or sending, an
        amplifier routed to the ADC pair, the open bridge's Command just sent), into the period in C."""
        ps = self._ps
        if not ps.enabled:
            return
        fdcan, opamps = self.fdcan, self._pair_opamps
        ps.wake = bool(
            self._off_seq is not None or self._rx or self._on_bus or self._idle_left or self._answer_left
            or self._bus_free > ps.period_start or self._hall_held is not None or self.boot_error is not None
            or (fdcan is not None and (fdcan.transmitted or (not self._bus_on and not fdcan.cccr & FDCAN_INIT)))
            or (opamps is not None and any(opamps[0].csr[k] & OPAINTOEN for k in opamps[1])))

    def _period_c(self, msg: Measurement) -> int | None:
        """The period in C for Measurement `msg`: its exec_time_ns, or None when Python runs it (and finishes it
        when the C period began it: `_period_resume`)."""
        ps = self._ps
        if not ps.enabled or ps.wake:
            return None
        assert self._adc_table is not None
        self._adc_table.take((msg.i_a, msg.i_b, msg.i_c, msg.vdc))
        self._table_in_c = True
        values, exec_time = self._c_args
        values[:] = [msg.i_a, msg.i_b, msg.i_c, msg.theta_e, msg.omega_m, msg.vdc]
        if period_native.library().hil_board_period(ctypes.byref(ps), values, ctypes.byref(exec_time)):
            self._frames_taken += 1  # `send` counted the frame already
            return int(exec_time.value)
        return None

    def _period_resume(self) -> int:
        """Finish the period the C period began and handed back (its inputs taken, its run begun: `resume`)."""
        ps = self._ps
        ps.resume = 0
        end = self._period_start + self.period_cycles
        if ps.resume_rc == period_native.BEFORE_RUN:  # a Python listener raised in the break comparator's call
            tim = self._tim1_c
            assert tim is not None
            tim.raise_held()
            snapshot = self._snapshot()
            self.board.run_until(end)
        else:
            snapshot = (ps.sleep0, ps.isr0, ps.entries0, ps.late0)
            self.board.finish_native(end, ps.resume_rc)
        return self._period_end(end, snapshot)

    def period_function(self) -> tuple[int, int] | None:
        """For a caller in C (the native loop's board link, after `native_io`'s inputs function filled the ADC
        table): (address of hil_board_period, its state) — `int fn(void *state, const double *values, int64_t
        *exec_time_ns)`, values i_a, i_b, i_c [A], theta_e [rad], omega_m [rad/s], vdc [V]; 1: the period ran,
        TIM1's outputs on; 0: call `measurement(native=True)`, which runs or finishes it —, or None (NATIVE_PERIOD
        off, or a model of the period in Python)."""
        if not self._ps.enabled:
            return None
        return core_native.address(period_native.library().hil_board_period), ctypes.addressof(self._ps)

    def _idle_legs(self) -> tuple[bool, ...] | None:
        """With TIM1's outputs off (MOE = 0): each leg's level when the timer drives its idle state (OSSI set and
        an output enabled: OCx = OISx, OCxN = OISxN after the dead time, CR2) — True the upper switch on, False the
        lower —, or None when no leg is driven (OSSI clear, or every output disabled: every switch off, the open
        bridge). A bridge driven in part, or a leg with both switches on, is not modelled: BoardError naming CR2."""
        tim = self.tim1
        if not tim.regs[TIM1_BDTR] >> 10 & 1:  # OSSI clear: the outputs are released, every gate off
            return None
        ccer, cr2 = tim.regs[TIM1_CCER], tim.regs[TIM1_CR2]
        legs: list[bool | None] = []
        for ch in self.desc.pwm_channels:
            upper = bool(ccer >> (4 * ch) & 1) and bool((cr2 >> (8 + 2 * ch) & 1) ^ (ccer >> (4 * ch + 1) & 1))
            lower = bool(ccer >> (4 * ch + 2) & 1) and bool((cr2 >> (9 + 2 * ch) & 1) ^ (ccer >> (4 * ch + 3) & 1))
            if upper and lower:
                raise BoardError(f"TIM1 CR2 0x{cr2:08x}, CCER 0x{ccer:08x}: with MOE = 0 the idle levels of channel "
                                 f"{ch + 1} turn both its switches on (OIS{ch + 1} and OIS{ch + 1}N active)")
            legs.append(True if upper else False if lower else None)
        if all(leg is None for leg in legs):
            return None
        if any(leg is None for leg in legs):
            raise BoardError(f"TIM1 CR2 0x{cr2:08x}, CCER 0x{ccer:08x}: with MOE = 0 the idle levels drive some legs "
                             "and leave others open, which the virtual board does not model (CR2 OISx/OISxN)")
        return tuple(bool(leg) for leg in legs)

    def outputs_off(self, seq: int) -> bool:
        """Whether the Command answering Measurement `seq` was sent with TIM1's outputs off and no leg driven
        (MOE = 0, the gates off: the open bridge that Command stands for)."""
        return self._off_seq == seq

    def first_duties(self, theta_e: float, omega_m: float) -> tuple[float, ...]:
        """The board's outputs over the run's first period, before its first Command (the host applies them in
        period 0), for the machine at electrical angle `theta_e` [rad] and mechanical speed `omega_m` [rad/s] at
        the period's start: with TIM1's outputs off (MOE = 0, as every firmware starts) the open bridge — no
        current flows, as on the chip, where the gates stay off until the firmware sets MOE —, else the compare
        values in force (no current yet: no dead-time correction)."""
        if not self.tim1.moe:
            idle = self._idle_legs()
            if idle is not None:
                return tuple(1.0 if upper else 0.0 for upper in idle)
            return self._open_bridge(theta_e, omega_m, self.vdc_v, 0.5)
        return self._compare_duties((0.0, 0.0, 0.0))

    def _outputs(self, seq: int, i_a: float, i_b: float, i_c: float, theta_e: float, omega_m: float,
                 vdc: float) -> tuple[float, ...] | int:
        """The outputs in force for the next period, answering Measurement `seq`: the compare values' duties with
        MOE set; with MOE = 0 the idle levels' switching state (an int) for the whole period when the timer drives
        them (the zero vector for the usual lower switches on), else the open bridge's duties."""
        self._off_seq = None
        duties = self._tim1.compare_duties(self.desc.pwm_channels, (i_a, i_b, i_c), self.hclk_hz, self.carrier_s)
        if duties is not None:  # MOE set
            return duties
        idle = self._idle_legs()
        if idle is not None:
            return sum(1 << (2 - j) for j, upper in enumerate(idle) if upper)
        self._off_seq = seq
        return self._open_bridge(theta_e, omega_m, vdc, 1.5)

    def _command(self, seq: int, outputs: tuple[float, ...] | int, exec_time_ns: int) -> Command:
        """The Command of `_outputs`."""
        if isinstance(outputs, int):
            return Command(seq=seq, states=(outputs,), durations_ns=(self.ts_ns,), exec_time_ns=exec_time_ns)
        return Command(seq=seq, states=(), durations_ns=(), duties=outputs, exec_time_ns=exec_time_ns)

    def measurement(self, seq: int, i_a: float, i_b: float, i_c: float, theta_e: float, omega_m: float,
                    vdc: float, native: bool = False) -> tuple[tuple[float, ...] | None, int] | None:
        """One control period for Measurement `seq`'s values (the decoded frame's) [A, rad, rad/s, V], as `send`
        runs it for a Measurement frame: (duties, exec_time_ns) of the duty-cycle Command that answers it, for the
        caller to encode and return before the frames queued here; None when the reply is queued here (a
        switching-state Command, or frames already waiting that it must follow). `native`: the caller holds
        `native_io`'s functions, has filled the ADC table with the inputs function (when it got one) and takes
        TIM1's compare duties (MOE set) from the outputs function (when it got one): duties None then."""
        t0 = time.perf_counter()
        self._stats.frames_tx += 1  # `stats` (link_shared.py: the C period's count added when read)
        bus = self.bus  # noqa: F841 - as `send`, which looks at the bus before the frames (it may join it now)
        if self.boot_error is not None:
            raise self.boot_error
        self._idle_left = 0
        self._answer_left = 0
        self._table_in_c = native
        # the period in C (link_board.c) may have taken the inputs and begun the run: `resume`
        exec_time_ns = self._period_resume() if self._ps.resume else self._period(i_a, i_b, i_c, theta_e, omega_m, vdc)
        out: tuple[tuple[float, ...] | None, int] | None = None
        if native and self._duties_in_c and not self._rx and self._tim1.moe:  # `_outputs` in C, by the caller
            self._off_seq = None
            out = (None, exec_time_ns)
        else:
            outputs = self._outputs(seq, i_a, i_b, i_c, theta_e, omega_m, vdc)
            if self._rx or isinstance(outputs, int):
                self._reply(self._command(seq, outputs, exec_time_ns))
            else:
                out = (outputs, exec_time_ns)
        self._collect()
        self._sync_wake()
        self._wall_s += time.perf_counter() - t0  # `wall_s` (link_shared.py: the C period's time added when read)
        return out

    def native_io(self) -> tuple[tuple[int, int] | None, tuple[int, int] | None]:
        """For a caller in C (the native loop's board link): (the inputs function, its argument) that fills the ADC
        pair's table from a Measurement's (i_a, i_b, i_c, vdc) [A, V] before `measurement(native=True)` — None when
        the conversions take their codes in Python (noise, amplifiers, the Python models) —, and (the outputs
        function, its argument) that computes the duties `measurement(native=True)` leaves to the caller from
        (i_a, i_b, i_c) — None when TIM1 is the Python model."""
        inputs = outputs = None
        if self._adc_table is not None:
            inputs = self._adc_table.take_function()
        function = getattr(self._tim1, "outputs_function", None)
        if function is not None and self.boot_error is None:
            outputs = function(self.desc.pwm_channels, self.hclk_hz, self.carrier_s)
            self._duties_in_c = True
        return inputs, outputs

    def _compare_duties(self, currents: tuple[float, float, float]) -> tuple[float, ...]:
        """The duties of TIM1's compare values in force (PWM mode, polarity), each shortened or lengthened by the
        dead time according to its phase current's sign when its complementary output is on (MOE set)."""
        duties = self.tim1.compare_duties(self.desc.pwm_channels, currents, self.hclk_hz, self.carrier_s)
        assert duties is not None
        return duties

    def _open_bridge(self, theta_e: float, omega_m: float, vdc: float, ahead: float) -> tuple[float, float, float]:
        """MOE = 0 (OSSI set: every switch off): the duties whose average phase voltages are those of an open
        bridge over a period — the machine's back EMF at zero current, e_x = -ωe·ψf·sin(θe - x·2π/3) at the
        period's middle (`ahead` carrier periods after the instant of `theta_e`: 1.5 for the period after a
        Measurement's, 0.5 for the period that starts there), centred between the rails. No current flows while
        the line back EMF stays below Vdc, as on the chip; above it the duties saturate at the rails (the
        freewheeling diodes clamp the line voltage to Vdc; the rectified current's exact shape is not modelled).
        The duty Command has no high-impedance form: this is its nearest exact equivalent. Without magnets (ψf =
        0) it is 0.5 on every leg."""
        we = self.pole_pairs * omega_m
        theta = theta_e + ahead * we * self.carrier_s
        amp = we * self.psi_f_wb
        emf = [-amp * math.sin(theta - k * 2 * math.pi / 3) for k in range(3)]
        if not amp or vdc <= 0.0 or not math.isfinite(amp):
            return (0.5, 0.5, 0.5)
        mid = (max(emf) + min(emf)) / 2
        a, b, c = (min(max(0.5 + (e - mid) / vdc, 0.0), 1.0) for e in emf)
        return (a, b, c)

    # --- Link -----------------------------------------------------------------------------------------------------

    @property
    def bus(self) -> Fdcan | None:
        """The FDCAN1 model once the firmware has taken its CAN controller out of initialisation (cleared
        CCCR.INIT: it is on the bus from then on, even while it re-enters INIT to reconfigure), else None: a
        firmware that never starts FDCAN1 has no bus and the board answers for it."""
        fdcan = self.fdcan
        if self.boot_error is not None:  # the firmware stopped in its start-up: the board answers for it
            return None
        if not self._bus_on and isinstance(fdcan, Fdcan) and not fdcan.cccr & FDCAN_INIT:
            self._bus_on = True
        return fdcan if self._bus_on else None

    def send(self, frames: Sequence[Frame]) -> None:
        t0 = time.perf_counter()
        bus = self.bus
        for frame in frames:
            self._stats.frames_tx += 1
            msg = self.decoder.feed(frame)
            if isinstance(msg, Measurement):
                if self.boot_error is not None:
                    raise self.boot_error
                self._idle_left = 0
                self._answer_left = 0
                self._table_in_c = False
                exec_time_ns = self._measured(msg)
                outputs = self._outputs(msg.seq, msg.i_a, msg.i_b, msg.i_c, msg.theta_e, msg.omega_m, msg.vdc)
                self._reply(self._command(msg.seq, outputs, exec_time_ns))
            elif bus is not None:  # on the bus one after the other, received at the end of its bus time
                message = can.Message(arbitration_id=frame.arbitration_id, data=frame.data, is_fd=frame.is_fd,
                                      bitrate_switch=frame.is_fd, is_extended_id=frame.arbitration_id > 0x7FF)
                self._bus_free = max(self._bus_free, self.board.now) + bus.frame_cycles(message)
                self._on_bus.append((self._bus_free, message))
                self._idle_left = IDLE_PERIODS
            elif isinstance(msg, ConfigParam):
                self.configs_acked += 1
                self._reply(ConfigAck(param_id=msg.param_id, value=msg.value, status=int(Status.OK)))
            elif isinstance(msg, Setpoint):
                self._setpoint(msg)
        self._collect()
        self._sync_wake()
        self._wall_s += time.perf_counter() - t0  # `wall_s` (link_shared.py: the C period's time added when read)

    def _measured(self, msg: Measurement) -> int:
        """`send`'s period for Measurement `msg`: in C when it can be (`_period_c`, as the native loop's board link
        calls it), else in Python; its exec_time_ns."""
        exec_time_ns = self._period_c(msg)
        if exec_time_ns is not None:
            return exec_time_ns
        if self._ps.resume:
            return self._period_resume()
        return self._period(msg.i_a, msg.i_b, msg.i_c, msg.theta_e, msg.omega_m, msg.vdc)

    def poll(self) -> Frame | None:
        ps = self._ps
        if ps.enabled and not ps.wake:  # nothing queued, no idle period due (`_sync_wake`): nothing to do
            return None
        frame = super().poll()
        self._sync_wake()
        return frame

    def requeue(self, frames: list[Frame]) -> None:
        super().requeue(frames)
        self._sync_wake()

    def _collect(self) -> bool:
        """The frames the firmware sent on FDCAN1, into the host's queue; whether one of them started after the
        last host frame arrived (an answer to it, not a frame sent before)."""
        bus = self.bus
        answered = False
        if bus is not None:
            for m in bus.take_transmitted():
                self._rx.append(Frame(int(m.arbitration_id), bytes(m.data), bool(m.is_fd)))
                start = round(float(m.timestamp) * self.board.sysclk_hz) - bus.frame_cycles(m)
                answered = answered or start >= self._last_arrival
        return answered

    def _idle_period(self) -> None:
        """A frame reached the firmware outside a control period (configuration, the safe stop): one period of the
        firmware with the last inputs held, so that it can answer (the host's plant is not advancing then)."""
        self._idle_left = max(self._idle_left - 1, 0)
        self._answer_left = max(self._answer_left - 1, 0)
        if self._hall_held is None:  # the rotor where the last period left it, until the next Measurement
            self._hall_held = self.pole_pairs * (self._theta_m + self._omega_m * self.period_cycles / self.hclk_hz)
        end = self._period_start + self.period_cycles
        if self._run_to(end):
            self._idle_left = IDLE_PERIODS  # from each frame's arrival
        self._period_start = end
        self._sync_encoder()
        self.idle_periods += 1
        if self._collect() and not self._on_bus and not self._sending():  # the firmware answered the last frame
            self._idle_left = self._answer_left = 0

    def _sending(self) -> bool:
        """FDCAN1 has a transmission requested or on the bus."""
        fdcan = self.fdcan
        return fdcan is not None and (fdcan.in_flight is not None or fdcan.txbrp != 0)

    def _deliver_queued(self) -> None:
        """A Measurement does not wait for the bus (it reaches the board's inputs, not FDCAN1): the host frames
        sent before it, still on the bus, are received now, in their order, so that the firmware takes them first
        as it would behind them on a real bus."""
        fdcan = self.fdcan
        while self._on_bus and fdcan is not None:
            fdcan.deliver(self._on_bus.popleft()[1], self.board.now)
            self._last_arrival = self.board.now
            self._answer_left = IDLE_PERIODS
        self._bus_free = min(self._bus_free, self.board.now)

    def _run_to(self, end: int) -> bool:
        """Run the firmware until cycle `end`, FDCAN1 receiving the host's frames on the bus as their bus time ends;
        whether a frame arrived."""
        arrived = False
        fdcan = self.fdcan
        while self._on_bus and self._on_bus[0][0] <= end and fdcan is not None:
            at, message = self._on_bus.popleft()
            self.board.run_until(at)
            fdcan.deliver(message, self.board.now)
            self._last_arrival = self.board.now
            arrived = True
        self.board.run_until(end)
        return arrived

    def _setpoint(self, sp: Setpoint) -> None:
        """Without a bus the firmware never sees a Setpoint: the board stands in for the gate driver's enable line.
        A disabling Setpoint trips TIM1's break (MOE cleared, BIF set, as the break input does) and the board
        confirms the idle inverter with a HeartbeatTarget; an enabling one is counted as dropped."""
        if sp.enable:
            self.setpoints_dropped += 1
            return
        self.tim1.trip_break()
        self._heartbeats = (self._heartbeats + 1) & 0xFF
        self._reply(Heartbeat(node=1, state=int(NodeState.IDLE), counter=self._heartbeats))

    def _reply(self, msg: Command | ConfigAck | Heartbeat) -> None:
        for frame in self.codec.encode(msg):
            self._rx.append(frame)

    def _idle_due(self) -> bool:
        """Frames for the firmware outside a period, still on the bus, or its answer still being sent."""
        return self._idle_left > 0 or bool(self._on_bus) or (self._answer_left > 0 and self._sending())

    def _poll_idle_period(self) -> None:
        self._idle_period()

    # --- what the run says ----------------------------------------------------------------------------------------

    def period_records(self, start: int) -> list[tuple[int, float, int, float, int]]:
        """Per control period from `start` on, as far as recorded: (period, handler time [µs], exception entries,
        CPU load (share of the period's cycles not asleep), late compare values); the run's log takes them block by
        block (src/pmsm_hil/hil/runner/board_log.py)."""
        end = len(self.isr_cycles)
        us = 1e6 / self.hclk_hz
        return [(k, self.isr_cycles[k] * us, self.entries_per_period[k],
                 1.0 - self.sleep_cycles[k] / self.period_cycles, self.late_per_period[k]) for k in range(start, end)]

    def metrics(self) -> dict[str, Any]:
        """The board's own metrics over the metrics window (the periods from `skip_periods`)."""
        board, tim = self.board, self.tim1
        if self.boot_error is not None:  # no carrier: the firmware stopped before TIM1 counted
            return {"mcu_clock_hz": float(board.hclk_hz), "board": self.desc.name,
                    "board_configs_acked": self.configs_acked, "board_setpoints_dropped": self.setpoints_dropped}
        window = slice(self.skip_periods, None)
        isr = np.asarray(self.isr_cycles[window], dtype=float)
        sleep = np.asarray(self.sleep_cycles[window], dtype=float)
        us = 1e6 / self.hclk_hz
        out: dict[str, Any] = {"mcu_clock_hz": float(self.hclk_hz), "board": self.desc.name,
                               "board_carrier_hz": 1.0 / self.carrier_s,
                               "board_dead_time_ns": tim.dead_time_s(self.hclk_hz) * 1e9,
                               "board_late_compares": sum(self.late_per_period),
                               "board_first_late_period": self.late_first_period,
                               "board_setpoints_dropped": self.setpoints_dropped,
                               "board_configs_acked": self.configs_acked, "board_idle_periods": self.idle_periods,
                               "board_break_trips": tim.break_trips}
        if len(isr):
            out["board_isr_time_us"] = stats(isr * us)
            out["board_cpu_load"] = float(1.0 - sleep.sum() / (len(sleep) * self.period_cycles))
        handlers = {}
        for exc, st in sorted(board.isr.items()):
            if not st.cycles:
                continue
            name = "SysTick" if exc == 15 else f"IRQ{exc - 16}" if exc >= 16 else f"exception {exc}"
            entry: dict[str, Any] = {"entries": st.entries, "time_us": stats(np.asarray(st.cycles) * us)}
            if st.latency:
                entry["latency_us"] = stats(np.asarray(st.latency) * us)
            handlers[name] = entry
        out["board_handlers"] = handlers
        samples = []
        for name in ("ADC1", "ADC2"):
            adc = board.peripherals.get(name)
            for at, _, _ in getattr(adc, "sample_log", [])[-16:]:
                samples.append(((at - tim.last_update) % self.period_cycles) * us)
        if samples:
            out["board_adc_sample_us"] = stats(np.asarray(samples))
        return out
