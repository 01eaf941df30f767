"""Write tests/data/store_v2.sqlite: a coefficient store as written by the release before the
sensor-calibration tables (schema version 2).  Run once with that release's code (it was:
the commit before the schema-v3 upgrade); the file is committed and read by
tests/test_store_migration.py.  Rows: two aircraft, a converged fit, a fit whose k3 failed,
and a flight recorded with two input files."""

from pathlib import Path

from flightrecon.store import CoefficientStore, FlightCoefficients
from flightrecon.store.schema import SCHEMA_VERSION

assert SCHEMA_VERSION == 2, "run this with the schema-v2 release"
out = Path(__file__).with_name("store_v2.sqlite")
out.unlink(missing_ok=True)
rows = [
    FlightCoefficients(aircraft_id="4K-AZ01", flight_id="F0412",
                       flight_date_utc="2024-05-01T10:00:00Z", duration_s=5400.0, k1=-0.012,
                       k2=-1.1e-4, k3=-0.021, branch=("negative",) * 3, converged=True,
                       residual_m=18.0, iterations=9, software_version="0.1.0",
                       settings={"rate_hz": 16.0},
                       input_hashes={"logs/f0412.parquet": "a" * 64}),
    FlightCoefficients(aircraft_id="4K-AZ01", flight_id="F0415",
                       flight_date_utc="2024-05-09T07:30:00Z", duration_s=4800.0, k1=-0.013,
                       k2=-2.0e-4, k3=float("nan"), branch=("negative", "negative", "none"),
                       converged=False, residual_m=float("nan"), iterations=40,
                       software_version="0.1.0", settings={},
                       input_hashes={"logs/f0415.csv": "b" * 64},
                       axis_converged=(True, True, False)),
    FlightCoefficients(aircraft_id="4K-AZ02", flight_id="F1",
                       flight_date_utc="2024-06-02T12:00:00Z", duration_s=900.0, k1=0.004,
                       k2=-3.0e-4, k3=-0.002, branch=("positive", "negative", "negative"),
                       converged=True, residual_m=2.5, iterations=12, software_version="0.1.0",
                       settings={"methods": None},
                       input_hashes={"circuit.parquet": "c" * 64,
                                     "circuit.meta.toml": "d" * 64}),
]
with CoefficientStore(out) as st:
    st.record_many(rows)
    st.con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    st.con.execute("PRAGMA journal_mode = DELETE")
print(out, out.stat().st_size)
