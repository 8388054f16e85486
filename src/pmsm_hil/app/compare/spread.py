"""Aggregate compare rows over the initial rotor angles: mean, min and max of every numeric metric."""

from __future__ import annotations

from typing import Any

from pmsm_hil.hil.metrics.registry import row_keys

#: row keys identifying one operating point of one run specification
GROUP_KEYS = ("group", "label", "controller", "ts_us", "speed_rpm", "load_nm")
#: numeric metrics aggregated: every compare-row metric of the registry
SPREAD_METRICS = row_keys()


def aggregate(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (group, label, Ts, speed, load) in first-seen order: each metric's mean, and
    `<metric>_min` / `<metric>_max` over the runs (initial rotor angles); `n_runs` runs, `n_trips` of
    them ended by the plant's protection, `end_reason` the first that is not "completed" (else
    "completed"). Metrics missing in a run are skipped."""
    groups: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
    for r in rows:
        key = tuple(r.get(k, r.get("controller") if k == "label" else None) for k in GROUP_KEYS)
        groups.setdefault(key, []).append(r)
    out: list[dict[str, Any]] = []
    for key, members in groups.items():
        agg: dict[str, Any] = dict(zip(GROUP_KEYS, key, strict=True))
        agg["n_runs"] = len(members)
        for m in SPREAD_METRICS:
            vals = [float(r[m]) for r in members if isinstance(r.get(m), int | float)]
            if vals:
                agg[m] = sum(vals) / len(vals)
                agg[f"{m}_min"] = min(vals)
                agg[f"{m}_max"] = max(vals)
            else:
                agg[m] = None
        reasons = [str(r.get("end_reason")) for r in members if r.get("end_reason") not in (None, "completed")]
        agg["n_trips"] = sum("trip" in reason for reason in reasons)
        agg["end_reason"] = reasons[0] if reasons else members[0].get("end_reason")
        out.append(agg)
    return out
