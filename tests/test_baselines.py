"""Dead-reckoning baselines (flightrecon.methods.baselines)."""

from pathlib import Path

import numpy as np

from flightrecon.cleaning import clean_flight
from flightrecon.geo.frames import output_plane
from flightrecon.ingest import load_flight
from flightrecon.methods.baselines import dead_reckoning

LOG = Path(__file__).resolve().parents[1] / "sample_logs" / "circuit.parquet"


def test_linear_correction_ends_at_arrival_and_starts_at_departure():
    clean = clean_flight(load_flight(LOG))
    raw = dead_reckoning(clean)
    cor = dead_reckoning(clean, corrected=True)
    ok = np.isfinite(cor["north_m"].to_numpy())
    first, last = np.flatnonzero(ok)[[0, -1]]
    arr = clean.meta.arrival
    ea, na, _ = output_plane(clean.meta).forward(arr.lat_deg, arr.lon_deg, arr.elev_m)
    assert abs(cor["north_m"].iloc[last] - float(na)) < 1e-6
    assert abs(cor["east_m"].iloc[last] - float(ea)) < 1e-6
    # the correction is zero at lift-off and the raw track starts at the departure point
    assert abs(cor["north_m"].iloc[first] - raw["north_m"].iloc[first]) < 1e-9
    assert np.hypot(raw["north_m"].iloc[first], raw["east_m"].iloc[first]) < 100.0
