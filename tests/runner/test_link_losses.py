"""Losses attributed to the link (src/pmsm_hil/hil/runner/link_losses.py): what each receiving end saw lost, and the
endings that name the link."""

from __future__ import annotations

from typing import Any

from pmsm_hil.hil.runner.link_losses import attribute


def _metrics(end_code: int, end_reason: str, missing: int = 0, **link: int) -> dict[str, Any]:
    return {"end_code": end_code, "end_reason": end_reason, "dut_violations_by_rule": {"missing": missing},
            "link": {"frames_rx": 10, **link}}


def test_a_watchdog_ending_with_losses_to_the_target_names_the_link() -> None:
    m = _metrics(3, "watchdog: target silent for 10 periods (1.0 ms); inverter put in the safe state")
    attribute(m, {"frames_rx": 5, "dropped": 2, "socket_drops": 3})
    assert m["link_losses"] == {"to_target": 5, "to_host": 0} and m["target_link"]["dropped"] == 2
    assert m["end_reason"].endswith("; the link lost 5 frame(s) to the target (link sequence gaps, socket buffer "
                                    "drops): the loss is the link's, not necessarily the target's")


def test_endings_the_link_did_not_cause_are_left_alone() -> None:
    for m in (_metrics(0, "completed", dropped=1), _metrics(4, "DUT contract violation ...: durations", dropped=1),
              _metrics(3, "plant trip: overcurrent", socket_drops=4), _metrics(4, "DUT ...: missing", missing=1)):
        reason = m["end_reason"]
        attribute(m, None)
        assert m["end_reason"] == reason and m["target_link"] is None and m["link_losses"]["to_target"] is None


def test_a_missing_command_ending_names_the_socketcan_link_whose_kernel_dropped_frames() -> None:
    m = _metrics(4, "DUT contract violation at period 12: missing", missing=1, kernel_dropped=7)
    m["link_spec"] = "socketcan:vcan0,fd=true"
    attribute(m, {"frames_rx": 5, "kernel_dropped": 2})
    assert m["link_losses"] == {"to_target": 2, "to_host": 7}
    assert m["end_reason"].endswith("; the kernel dropped 7 frame(s) received by the host and 2 frame(s) received "
                                    "by the target on link socketcan:vcan0,fd=true (SocketCAN receive buffer full: "
                                    "link.kernel_dropped)")
