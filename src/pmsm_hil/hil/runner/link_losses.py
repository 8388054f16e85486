"""Losses attributed to the link: the target's own link counters beside the host's (metrics.json `target_link`),
the frames each direction lost on the link (`link_losses`: link sequence gaps, receive-buffer drops of the
kernel), and an ending that blames a missing Command or a silent target says when the link lost frames.
"""

from __future__ import annotations

from typing import Any

from pmsm_hil.hil.runner.contract import MISSING, EndCode
from pmsm_hil.hil.runner.target_setup import TargetConnection


def target_link_stats(conn: TargetConnection) -> dict[str, int] | None:
    """The target end's own link counters: a spawned target's (printed when it stopped), an in-process target's
    end of the link; None when the host cannot know them (an external target, the native loop's core)."""
    if conn.process is not None:
        return dict(conn.target_link_stats) or None
    if conn.target_link is not None:
        stats: dict[str, int] = conn.target_link.stats.as_dict()
        return stats
    return None


def _lost(stats: dict[str, Any] | None) -> int | None:
    """Frames lost on the way to the end whose counters these are: gaps in the peer's link sequence numbers plus
    datagrams its socket buffer dropped plus frames its SocketCAN kernel dropped (None: not known)."""
    if stats is None:
        return None
    return int(stats.get("dropped", 0)) + int(stats.get("socket_drops") or 0) + int(stats.get("kernel_dropped") or 0)


def _kernel_drops(metrics: dict[str, Any], target_link: dict[str, int] | None) -> str:
    """'; the host kernel dropped N frame(s) received on LINK ...' when a SocketCAN receive buffer overflowed
    (the host's end, the target's end), else ''."""
    host = int((metrics.get("link") or {}).get("kernel_dropped") or 0)
    target = int((target_link or {}).get("kernel_dropped") or 0)
    if not (host or target):
        return ""
    ends = " and ".join(f"{n} frame(s) received by the {end}" for n, end in ((host, "host"), (target, "target")) if n)
    return (f"; the kernel dropped {ends} on link {metrics.get('link_spec') or '?'} (SocketCAN receive buffer "
            f"full: link.kernel_dropped)")


def _auth_dropped(stats: dict[str, Any] | None) -> int | None:
    """Frames the end whose counters these are dropped for their authentication: a MAC that failed or was missing,
    a replayed freshness value (None: not known)."""
    if stats is None:
        return None
    return int(stats.get("auth_failed", 0)) + int(stats.get("auth_replayed", 0))


def attribute(metrics: dict[str, Any], target_link: dict[str, int] | None) -> None:
    """Add `target_link`, `link_losses` and `link_auth_dropped` {to_target, to_host} to `metrics`; when the run
    ended on a missing Command or the watchdog and the link lost frames, the end reason says so."""
    metrics["target_link"] = target_link
    to_target, to_host = _lost(target_link), _lost(metrics.get("link"))
    metrics["link_losses"] = {"to_target": to_target, "to_host": to_host}
    metrics["link_auth_dropped"] = {"to_target": _auth_dropped(target_link),
                                    "to_host": _auth_dropped(metrics.get("link"))}
    code = metrics.get("end_code")
    missing = metrics.get("dut_violations_by_rule", {}).get(MISSING, 0)
    silent = code == int(EndCode.SAFETY_STOP) and str(metrics.get("end_reason", "")).startswith("watchdog")
    if not ((code == int(EndCode.DUT_VIOLATION) and missing) or silent) or not (to_target or to_host):
        return
    parts = [f"{n} frame(s) to the {where}" for n, where in ((to_target, "target"), (to_host, "host")) if n]
    metrics["end_reason"] = (f"{metrics['end_reason']}; the link lost {' and '.join(parts)} (link sequence gaps, "
                             f"socket buffer drops): the loss is the link's, not necessarily the target's"
                             + _kernel_drops(metrics, target_link))


__all__ = ["attribute", "target_link_stats"]
