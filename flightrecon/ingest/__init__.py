"""Ingest: read recorder logs (CSV, Parquet), map foreign columns, merge measurement files,
read flight metadata and validate everything into a :class:`flightrecon.types.Flight`.

Public API::

    load_flight(log, *, gnss=None, radar=None, mapping=None, sidecar=None,
                meta_overrides=None, allow_unsorted=False, gnss_use=None) -> Flight
    GnssUse(withhold=, withhold_s=, interval_s=, h_sd_m=, v_sd_m=)   (how the GNSS is used)
    parse_position("LAT,LON,ELEV_M") -> Position
    load_sidecar(path) -> Sidecar;  discover_sidecar(log) -> Path | None
    load_mapping(path) -> Mapping
    read_table(path) -> RawTable
    describe_flight(flight) -> dict        (what ``flightrecon info`` prints)
"""

from flightrecon.ingest.api import load_flight
from flightrecon.ingest.describe import describe_flight
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.ingest.mapping import Mapping, load_mapping
from flightrecon.ingest.readers import RawTable, read_table
from flightrecon.ingest.sidecar import (
    Sidecar,
    apply_overrides,
    discover_sidecar,
    load_sidecar,
    parse_position,
)

__all__ = [
    "GnssUse",
    "Mapping",
    "RawTable",
    "Sidecar",
    "apply_overrides",
    "describe_flight",
    "discover_sidecar",
    "load_flight",
    "load_mapping",
    "load_sidecar",
    "parse_position",
    "read_table",
]
