"""The firmware's controller table as seen from Python (`CONTROLLERS`, read through cffi): one entry per
DBC controller name and id, with the phase count the firmware enforces on measurement frames."""

from __future__ import annotations

import pytest

from pmsm_hil.protocol.ids import CONTROLLER_NAMES, RESERVED_CONTROLLER_IDS, ControllerId, Status
from pmsm_hil.sim_target.firmware import (
    CONTROLLERS,
    ControllerInfo,
    Firmware,
    FirmwareConfigError,
    controller_by_name,
    controller_phases,
)


def test_one_entry_per_dbc_controller() -> None:
    counted = sorted((k, v) for k, v in CONTROLLER_NAMES.items() if k not in RESERVED_CONTROLLER_IDS)
    assert [(c.id, c.name) for c in CONTROLLERS] == [(int(k), v) for k, v in counted]
    assert all(c.implemented for c in CONTROLLERS)
    assert controller_by_name("off") == ControllerInfo("off", int(ControllerId.OFF), 0, True)
    assert {c.phases for c in CONTROLLERS if c.id != ControllerId.OFF} == {3, 6}


def test_lookups() -> None:
    assert controller_by_name("mptc2").phases == 6 and controller_by_name("fcs-mpc-1").id == 2
    assert controller_phases(int(ControllerId.FOC)) == 3
    with pytest.raises(FirmwareConfigError, match=r"'nope'.*known: off, mpcc"):
        controller_by_name("nope")
    with pytest.raises(FirmwareConfigError, match="controller_id 99"):
        controller_phases(99)
    with pytest.raises(FirmwareConfigError, match="'external': unknown to the firmware"):
        controller_by_name("external")  # a DBC name reserved for foreign firmware, not in the table


def test_the_reference_firmware_rejects_the_external_id() -> None:
    fw = Firmware()
    with pytest.raises(FirmwareConfigError, match="controller"):
        fw.select_controller(int(ControllerId.EXTERNAL))


@pytest.mark.parametrize("info", [c for c in CONTROLLERS if c.id != ControllerId.OFF], ids=lambda c: c.name)
def test_firmware_takes_frames_of_the_table_phase_count(info: ControllerInfo) -> None:
    fw = Firmware()
    fw.select_controller(info.id)
    other = 3 if info.phases == 6 else 6
    assert fw.step(0, [0.0] * info.phases, 0.0, 0.0, 300.0, 0).status == Status.OK
    assert fw.step(1, [0.0] * other, 0.0, 0.0, 300.0, 100_000).status == Status.INVALID_CONFIG
