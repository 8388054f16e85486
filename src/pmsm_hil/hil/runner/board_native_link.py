"""The native loop's link to the virtual STM32G4 board running register-level firmware (`--target stm32g4:FW.elf`,
src/pmsm_hil/sim_target/stm32g4/link.py): the C link of src/pmsm_hil/hil/runner/c/links/link_board.h.

Per period the C loop's Measurement frame is decoded in C and reaches the board through one call with plain numbers
(`on_board_period`); the duty-cycle Command the board answers with comes back as numbers and is encoded in C. The
period's pin voltages go into the ADC pair's table, and TIM1's compare duties come out of the timer's model, through
the models' own C functions called by the C link (`BoardLink.native_io`), not through Python; and the common period
itself runs in C (`BoardLink.period_function`, c/board_period.c) with no Python call. Every other frame, and
a reply the board keeps in its own queue (a switching-state Command, its FDCAN1 frames, configuration answers), goes
through the callback link as before; a receive calls Python only while the board says it may have something
(`BoardLink.pending`). With link faults injected (`--fault`), which act on each frame in Python, it is the callback
link alone.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from pmsm_hil.hil.runner.callback_link import NativePyLink
from pmsm_hil.protocol.codec import L_MEAS_FD
from pmsm_hil.protocol.frame import Frame

if TYPE_CHECKING:
    from pmsm_hil.sim_target.stm32g4.link import BoardLink

_DEFINED: set[int] = set()


def _define_period(ffi: Any) -> None:
    """Define `nl_py_board_period` of the loop extension once (cffi `extern "Python"`)."""
    if id(ffi) in _DEFINED:
        return

    @ffi.def_extern()  # type: ignore[untyped-decorator]
    def nl_py_board_period(ctx: Any, m: Any, cmd: Any) -> int:
        bridge: NativeBoardLink = ffi.from_handle(ctx)
        try:
            return bridge.on_board_period(m, cmd)
        except BaseException as exc:  # the loop thread must not unwind through C
            bridge.fail(exc)
            return -1

    _DEFINED.add(id(ffi))


class NativeBoardLink(NativePyLink):
    """The callback link to a `BoardLink`, with the Measurement and its duty-cycle Command in C (link_board.h)."""

    #: the ADC pair's table and TIM1's compare duties filled and read by the C link through the models' own C
    #: functions (`BoardLink.native_io`; False: by the board in Python, which gives the same records)
    NATIVE_IO = True

    def __init__(self, link: BoardLink, ffi: Any, lib: Any, fd: bool,
                 pump: Callable[[], object] | None = None) -> None:
        super().__init__(link, ffi, lib, fd, pump=pump)
        _define_period(ffi)
        self.board = link
        self._board_state: Any = None
        self._native_io = False
        self._duties_form = int(lib.NL_BOARD_DUTIES)
        self._outputs_form = int(lib.NL_BOARD_OUTPUTS)

    def attach(self, c: Any, lockstep_timeout_s: float) -> None:
        """Give the loop's nl_config_t `c` the board's C link (the callback link alone with faults injected)."""
        super().attach(c, lockstep_timeout_s)
        if self.faulty is not None:
            return
        st = self.ffi.new("nl_board_link_t *")
        self.lib.nl_py_board_link(self._c_link, st, self._handle)
        st.scale_i = L_MEAS_FD.signal("i_a").scale
        st.scale_theta = L_MEAS_FD.signal("theta_e").scale
        st.scale_omega = L_MEAS_FD.signal("omega_m").scale
        st.scale_vdc = L_MEAS_FD.signal("vdc").scale
        inputs, outputs = self.board.native_io() if self.NATIVE_IO else (None, None)
        self._native_io = self.NATIVE_IO
        if inputs is not None:
            st.inputs = self.ffi.cast("nl_board_inputs_fn", inputs[0])
            st.inputs_user = self.ffi.cast("void *", inputs[1])
        if outputs is not None:
            st.outputs = self.ffi.cast("nl_board_outputs_fn", outputs[0])
            st.outputs_user = self.ffi.cast("void *", outputs[1])
        fast = self.board.period_function() if inputs is not None and outputs is not None else None
        if fast is not None:  # the common period without Python (c/board_period.c)
            st.fast = self.ffi.cast("nl_board_fast_fn", fast[0])
            st.fast_user = self.ffi.cast("void *", fast[1])
        st.py_pending = 1 if self.board.pending() else 0
        self._board_state = st

    def detach(self) -> None:
        """After the run: the Commands the C link returned join the board link's frame count, and one it still
        holds (a run stopped between a Measurement and its reply) goes back to the front of the board's queue,
        where the callback link would have left it."""
        st = self._board_state
        if st is not None:
            self.stats.frames_rx += int(st.stats.frames_rx)
            st.py_pending = 0
            f = self.ffi.new("hil_core_frame_t *")
            held = []
            while self.lib.nl_board_recv(st, f, 0) == 1:
                held.append(Frame(int(f.id), bytes(self.ffi.buffer(f.data, f.len)), bool(f.fd)))
            self.board.requeue(held)
            self._board_state = None
        super().detach()

    # --- the callbacks (the loop's thread) ---------------------------------------------------------------------
    def on_board_period(self, m: Any, cmd: Any) -> int:
        """One control period for the decoded Measurement `m` (nl_board_meas_t); the duty Command into `cmd`
        (nl_board_cmd_t) when the board leaves it to C: 0."""
        board = self.board
        out = board.measurement(m.seq, m.i_a, m.i_b, m.i_c, m.theta_e, m.omega_m, m.vdc, self._native_io)
        if out is not None:
            duties, cmd.exec_time_ns = out
            if duties is None:  # TIM1's compare duties: the C link asks the timer's model (link_board.h outputs)
                cmd.form = self._outputs_form
            else:
                cmd.duties = duties
                cmd.form = self._duties_form
        self._board_state.py_pending = 1 if board.pending() else 0
        return 0

    def on_send(self, f: Any) -> int:
        """Any frame but a Measurement: as the callback link."""
        result = super().on_send(f)
        self._sync_pending()
        return result

    def on_recv(self, f: Any, deadline_ns: int) -> int:
        """What the board queued in Python: as the callback link."""
        result = super().on_recv(f, deadline_ns)
        self._sync_pending()
        return result

    def _sync_pending(self) -> None:
        st = self._board_state
        if st is not None:
            st.py_pending = 1 if self.board.pending() else 0
