"""The dashboard layout as a Rerun blueprint, built in code (`build_blueprint`)."""

from __future__ import annotations

import rerun.blueprint as rrb

from pmsm_hil.dashboards import entities as ent
from pmsm_hil.dashboards.errors import DashboardError

#: Visible window of the scrolling time-series views [s].
DEFAULT_WINDOW_S = 0.1


def _series(name: str, origin: str, window_s: float) -> rrb.TimeSeriesView:
    rng = rrb.VisibleTimeRange(ent.TIMELINE, start=rrb.TimeRangeBoundary.cursor_relative(seconds=-window_s),
                               end=rrb.TimeRangeBoundary.cursor_relative())
    return rrb.TimeSeriesView(origin=origin, name=name, time_ranges=rng)


def build_blueprint(*, phases: int = 3, vdc: float = 48.0, window_s: float = DEFAULT_WINDOW_S) -> rrb.Blueprint:
    """Torque + reference + rolling ripple, phase currents, speed, αβ plane (hexagon, candidates, selected
    vector; x-y plane for six phases), execution time trace and histogram, switching frequency.

    `vdc` [V] sets the αβ view bounds; `window_s` [s] the scrolling window of the time series."""
    if phases not in (3, 6):
        raise DashboardError(f"phases: expected 3 or 6, got {phases}")
    if not vdc > 0.0:
        raise DashboardError(f"vdc: expected > 0 V, got {vdc}")
    r = 0.75 * vdc
    bounds = rrb.VisualBounds2D(x_range=[-r, r], y_range=[-r, r])
    planes: list[rrb.View] = [rrb.Spatial2DView(origin="/ab", name="αβ voltage plane [V]", visual_bounds=bounds)]
    if phases == 6:
        planes.append(rrb.Spatial2DView(origin="/xy", name="x-y voltage plane [V]", visual_bounds=bounds))
    rows = [_series("torque [N·m]", "/torque", window_s),
            _series("torque ripple, rolling RMS [N·m]", "/ripple", 20 * window_s),
            _series("phase currents [A]", "/currents", window_s)]
    if phases == 6:
        rows.append(_series("x-y currents [A]", "/xy_currents", window_s))
    rows.append(_series("speed [rpm]", "/speed", 20 * window_s))
    left = rrb.Vertical(*rows, row_shares=[3, 2, 3, 2, 2][:len(rows)] if phases == 6 else [3, 2, 3, 2])
    right = rrb.Vertical(
        rrb.Horizontal(*planes),
        rrb.Horizontal(
            _series("execution time [µs]", "/timing", window_s),
            rrb.BarChartView(origin="/timing_histogram", name="execution time histogram (count per µs bin)"),
        ),
        _series("switching frequency f_av, rolling [kHz]", "/switching", 20 * window_s),
        row_shares=[4, 3, 2],
    )
    return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[3, 2]), collapse_panels=True)
