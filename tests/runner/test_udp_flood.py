"""Links that junk cannot stop: a spawned target over UDP beside a local flood of ~100k junk
datagrams/s to both ports completes at the right speed and torque with no frame lost (both sockets are
connect()ed to their peer, so the kernel drops the junk before them). Timing-dependent: the flood takes a core."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.protocol.links.wire_bus import free_udp_ports

FLOOD = Path(__file__).with_name("udp_flood.py")
RATE = 100_000  # datagrams/s to both ports together


@pytest.mark.timing
@pytest.mark.parametrize(("loop", "duration"), [("native", "0.5"), ("python", "0.05")])
def test_a_spawned_udp_run_beside_a_flood_completes_at_speed_and_torque(loop: str, duration: str,
                                                                        tmp_path: Path) -> None:
    a, b = free_udp_ports()
    flood = subprocess.Popen([sys.executable, str(FLOOD), f"{a},{b}", str(RATE), "50"], stdout=subprocess.PIPE,
                             text=True)
    try:
        assert flood.stdout is not None and flood.stdout.readline().strip() == "flooding"
        out = tmp_path / "m.json"
        rc = main(["run", "--link", f"udp:{a}:{b}", "--target", "spawn", "--loop", loop, "--settle", "0.05",
                   "--duration", duration, "--json", str(out)])
    finally:
        flood.terminate()
        report = flood.communicate(timeout=30)[0]
    sent, seconds = report.split()[1], report.split()[3]
    assert int(sent) / float(seconds) > 0.5 * RATE, report  # the flood ran beside the whole run
    m = json.loads(out.read_text(encoding="utf-8"))
    assert rc == m["end_code"] == 0, m["end_reason"]
    assert m["loop"] == loop and m["safe_stop_confirmed"] is True
    assert abs(m["speed_mean_rpm"] - 1500.0) <= 15.0 and abs(m["torque_mean_nm"] - 7.0) <= 0.14
    assert m["link"]["lost"] == 0 and m["link_losses"] == {"to_target": 0, "to_host": 0}
    target = m["target_link"]
    assert target["frames_rx"] == m["link"]["frames_tx"] and m["link"]["frames_rx"] == target["frames_tx"]
