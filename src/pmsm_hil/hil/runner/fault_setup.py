"""Link fault injection in a run (`--fault`): the host's link wrapped in a `FaultyLink`, its clock, and the
injected faults as FAULT_DTYPE records for the MCAP (docs/runner.md, "Link fault injection")."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pmsm_hil.hil.records import FAULT_DTYPE, FAULT_KINDS
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.protocol.links.faults import FaultSpec, FaultyLink

_KIND_INDEX = {kind: i for i, kind in enumerate(FAULT_KINDS)}


def install_faults(client: TargetClient, spec: FaultSpec, clock: Callable[[], float]) -> FaultyLink:
    """Wrap the client's link; `clock()` is the run time [s]. Every link kind has an integrity check (CAN CRC,
    the serial and UDP CRC-16), so a corrupted frame is caught there: counted and dropped. An in-process
    target is served after the delayed frames due are released."""
    faulty = FaultyLink(client.link, spec, clock, crc_checked=True)
    client.link = faulty
    client.pump = pump_after_faults(faulty, client.pump)
    return faulty


def pump_after_faults(faulty: FaultyLink, serve: Callable[[], object] | None) -> Callable[[], None] | None:
    """The pump of an in-process target (`serve`, None: none) behind a FaultyLink: the delayed frames due are
    released first, then the target is served."""
    if serve is None:
        return None

    def pump() -> None:
        faulty.pump()
        serve()

    return pump


def fault_records(faulty: FaultyLink, ts_s: float) -> np.ndarray:
    """The faults injected since the last call as FAULT_DTYPE records (period index from t and Ts [s])."""
    events = faulty.take_events()
    out = np.zeros(len(events), dtype=FAULT_DTYPE)
    for i, ev in enumerate(events):
        out[i] = (ev.t_s, max(int(ev.t_s / ts_s + 1e-9), 0), 0 if ev.direction == "up" else 1,
                  _KIND_INDEX[ev.kind], ev.arbitration_id)
    return out


__all__ = ["fault_records", "install_faults"]
