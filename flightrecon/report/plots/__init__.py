"""Figures of a reconstruction (matplotlib, Agg backend), drawn for an investigator.

Every figure takes a :class:`ReportContext` (the result table, the summary, and optionally the
recorder's channels, the truth of a simulated flight and its sensor truth) and returns a
:class:`matplotlib.figure.Figure`, or ``None`` when the data hold nothing to show.

Conventions: time axes in UTC (seconds from the record start when the epoch is unknown);
altitudes above mean sea level (ellipsoidal height minus the flight's geoid undulation) and
pressure altitude (standard atmosphere, 1013.25 hPa) in metres with feet on the right axis;
wind as the direction it blows *from* (true, degrees) and its speed in m/s and knots; bands are
2 sigma; numbered markers are the rows of the events table.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import pandas as pd
from matplotlib.figure import Figure

from flightrecon.report.plots.context import (
    COLOURS,
    FPM,
    FT,
    G0,
    KT,
    METHOD_NAMES,
    PREFIXES,
    ReportContext,
    event_numbers,
    mark_events,
)
from flightrecon.report.plots.diagnostics import (
    CORRECTIONS,
    air_data_error,
    correction_rows,
    innovation_statistics,
    method_differences,
    newton_history,
    sensor_corrections,
)
from flightrecon.report.plots.ground_track import ground_track
from flightrecon.report.plots.time_series import (
    wind_from_speed,
    altitude_profile,
    attitude,
    load_factors,
    speeds,
    wind,
)

__all__ = [
    "COLOURS", "CORRECTIONS", "FIGURES", "FPM", "FT", "G0", "KT", "METHOD_NAMES", "PREFIXES",
    "ReportContext", "wind_from_speed", "air_data_error", "altitude_profile", "attitude",
    "correction_rows", "event_numbers", "ground_track", "innovation_statistics", "load_factors",
    "make_figures", "make_figures_ctx", "mark_events", "method_differences", "newton_history",
    "sensor_corrections", "speeds", "wind",
]

#: figure name -> (function, caption)
FIGURES: dict[str, tuple[Callable[[ReportContext], Figure | None], str]] = {
    "ground_track": (ground_track, "Ground track on a latitude/longitude grid"),
    "altitude_profile": (altitude_profile, "Altitude (MSL) and pressure altitude"),
    "speeds": (speeds, "Ground speed, airspeed and vertical speed"),
    "attitude": (attitude, "Attitude: roll, pitch, heading"),
    "load_factors": (load_factors, "Load factors"),
    "wind": (wind, "Wind: direction-from and speed"),
    "method_differences": (method_differences, "Methods compared"),
    "air_data_error": (air_data_error, "ADS/ARMS air-data error"),
    "sensor_corrections": (sensor_corrections, "Estimated sensor corrections"),
    "innovations": (innovation_statistics, "Innovation statistics"),
    "newton_history": (newton_history, "Sabziev Newton-Raphson iterations"),
}


def make_figures(track: pd.DataFrame, summary: Mapping[str, Any],
                 truth: pd.DataFrame | None = None, *, grid: pd.DataFrame | None = None,
                 gnss: pd.DataFrame | None = None,
                 sensor_truth: Mapping[str, Any] | None = None,
                 radar: pd.DataFrame | None = None) -> dict[str, Figure]:
    """Every figure the result supports, by name (see :data:`FIGURES`)."""
    ctx = ReportContext(track, summary, truth, grid, gnss, sensor_truth, radar)
    return make_figures_ctx(ctx)


def make_figures_ctx(ctx: ReportContext) -> dict[str, Figure]:
    out = {}
    for name, (fn, _caption) in FIGURES.items():
        fig = fn(ctx)
        if fig is not None:
            out[name] = fig
    return out

