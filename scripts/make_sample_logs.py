"""Regenerate sample_logs/ deterministically (docs/simulator.md, "Sample logs").

    python scripts/make_sample_logs.py [OUTDIR]

Writes, for circuit, regional, seed-ads-arms and landing: ``<name>.parquet`` and ``<name>.csv``
(the same log), ``<name>.truth.parquet``, ``<name>.meta.toml``, ``<name>.sensors.json``; and
``foreign.csv`` with ``foreign.mapping.toml``, ``foreign.meta.toml``, ``foreign.truth.parquet``,
``foreign.sensors.json``.  Rates are lowered from the scenario defaults to keep the folder
small (under 8 MB).  Files starting with ``handmade`` are not touched.
"""

from __future__ import annotations

import sys
from pathlib import Path

from flightrecon.export.atomic import write_text_atomic
from flightrecon.sim import simulate, write_simulation
from flightrecon.sim.foreign import FOREIGN_MAPPING_TOML, foreign_log
from flightrecon.sim.io import write_frame

SAMPLES = {
    "circuit": {"seed": 101, "truth_rate_hz": 8.0, "loads_hz": 8.0, "attitude_hz": 8.0},
    "regional": {"seed": 102, "truth_rate_hz": 2.0, "loads_hz": 2.0, "attitude_hz": 2.0,
                 "airspeed_hz": 2.0, "baro_hz": 2.0, "doppler_hz": 2.0},
    "seed-ads-arms": {"seed": 103},
    "landing": {"seed": 104, "truth_rate_hz": 4.0, "loads_hz": 4.0, "attitude_hz": 4.0},
}
FOREIGN = {"seed": 105, "truth_rate_hz": 4.0, "loads_hz": 4.0, "attitude_hz": 4.0,
           "airspeed_hz": 4.0, "baro_hz": 4.0, "gnss_hz": 0.0, "flight_id": "FX"}


def main(outdir: Path) -> None:
    outdir.mkdir(parents=True, exist_ok=True)
    for name, kw in SAMPLES.items():
        r = simulate(name, **kw)
        write_simulation(r, outdir / f"{name}.parquet")
        write_simulation(r, outdir / f"{name}.csv")
        print(f"{name}: {len(r.log)} rows, {r.truth.t_s.iloc[-1]:.0f} s")
    r = simulate("circuit", **FOREIGN)
    written = write_simulation(r, outdir / "foreign.parquet")
    written["log"].unlink()  # the foreign sample is CSV only, in vendor columns
    write_frame(foreign_log(r.log, r.truth, r.meta.epoch_utc), outdir / "foreign.csv")
    write_text_atomic(outdir / "foreign.mapping.toml", FOREIGN_MAPPING_TOML)
    print(f"foreign: {len(r.log)} rows")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[1]
         / "sample_logs")
