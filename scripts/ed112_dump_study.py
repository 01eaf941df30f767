"""A parameter dump of a flight data recorder read with no mapping against the same recorder
export read through its mapping (docs/ingest.md, "Parameter dumps of a flight data recorder";
issue 49, item 6).

Each flight is simulated (``flightrecon simulate SCENARIO [--airframe A] --seed S``), written
with its ED-112 minimum-rate export (``--export ed112``: a ``TIME`` column, the mapping beside
it), and that export is rewritten as a flight-data team's parameter dump (:func:`write_dump`):
the header of mnemonics, the units line under it, eight rows a subframe, each sample in the row
of its frame slot, ``FRAME`` and ``SUBFRAME`` counters as the time (across a wrap of the 12-bit
frame counter), the lateral load positive right.  Both are reconstructed recorder only
(``--no-gnss``, the sidecar's departure and arrival) by the joint smoother with the default
settings; the table gives the horizontal RMS from the truth over the airborne samples and the
mean NEES per horizontal axis.

Usage::

    python scripts/ed112_dump_study.py                 # the default flights, seed 5
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.ingest import load_flight
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.pipeline import ReconstructSettings, run_method
from flightrecon.sim import simulate, write_simulation
from flightrecon.sim.ed112 import ED112_PARAMETERS, ed112_export
from flightrecon.sim.io import write_export

#: rows a subframe (one second) of the dump: the fastest parameter's rate (VRTG, 8 Hz)
ROWS_PER_S = 8
#: the first frame's counter: the 12-bit counter wraps two frames in
FIRST_FRAME = 4094
FLIGHTS = (("circuit", None), ("jsbsim-circuit", "737"), ("jsbsim-circuit", "c172p"))
"""(scenario, airframe): the point-mass circuit and two JSBSim circuits."""


def write_dump(folder: Path, ex: pd.DataFrame, name: str = "dump.csv",
               lat_positive_left: bool = False) -> tuple[Path, np.ndarray]:
    """The ED-112 export ``ex`` (:func:`flightrecon.sim.ed112.ed112_export`) as a parameter
    dump: one row per eighth of a second, each sample in the row of its slot, ``FRAME`` and
    ``SUBFRAME`` counters (four subframes a frame, 1-based, from :data:`FIRST_FRAME`), the
    header of the export's mnemonics and the units line under it; the lateral load positive
    right unless ``lat_positive_left`` (the export's own sign).  Returns the path and each
    row's time [s from the first row]."""
    j = np.floor(ex["TIME"].to_numpy() * ROWS_PER_S + 1e-9).astype(int)
    n = int(j.max()) + 1
    n -= n % (4 * ROWS_PER_S)                   # whole frames
    sec = np.arange(n) // ROWS_PER_S
    out = {"FRAME": (FIRST_FRAME + sec // 4) % 4096, "SUBFRAME": sec % 4 + 1}
    units = ["", ""]
    for p in ED112_PARAMETERS:
        if p.column not in ex.columns:
            continue
        col = np.full(n, np.nan)
        ok = ex[p.column].notna().to_numpy() & (j < n)
        col[j[ok]] = ex[p.column].to_numpy()[ok]
        out[p.column] = col if (p.channel != "n_lat_g" or lat_positive_left) else -col
        units.append(p.unit)
    df = pd.DataFrame(out)
    path = folder / name
    with open(path, "w") as fh:
        fh.write(",".join(df.columns) + "\n" + ",".join(units) + "\n")
        df.to_csv(fh, header=False, index=False, na_rep="")
    return path, np.arange(n) / ROWS_PER_S


def errors(track: pd.DataFrame, truth: pd.DataFrame, sel: np.ndarray) -> dict[str, float]:
    """RMS horizontal error [m] and mean NEES per horizontal axis of the joint's ``track`` at
    the truth samples ``sel`` inside its span."""
    t = truth["t_s"].to_numpy()[sel]
    tt = track["t_s"].to_numpy(float)

    def at(col: str) -> np.ndarray:
        return np.interp(t, tt, track[f"joint_{col}"].to_numpy(float))
    en = at("north_m") - truth["north_m"].to_numpy()[sel]
    ee = at("east_m") - truth["east_m"].to_numpy()[sel]
    sn, se = at("north_sd_m"), at("east_sd_m")
    ok = (t >= tt[0]) & (t <= tt[-1]) & np.isfinite(en) & np.isfinite(ee) & (sn > 0) & (se > 0)
    return {"rms_h_m": float(np.sqrt(np.mean(en[ok] ** 2 + ee[ok] ** 2))),
            "nees_n": float(np.mean((en[ok] / sn[ok]) ** 2)),
            "nees_e": float(np.mean((ee[ok] / se[ok]) ** 2))}


def one_flight(scenario: str, airframe: str | None, seed: int, tmp: Path) -> list[str]:
    """The table rows of one flight: the export through its mapping, the dump with none."""
    r = simulate(scenario, seed, **({"airframe": airframe} if airframe else {}))
    log = tmp / f"{scenario}-{airframe or 'pm'}-{seed}.parquet"
    write_simulation(r, log)
    write_export(r, log, "ed112")
    dep = r.meta.departure
    ex = ed112_export(r.log, lat_deg=dep.lat_deg, lon_deg=dep.lon_deg,
                      epoch_utc=r.meta.epoch_utc)
    dump, _ = write_dump(tmp, ex, name=log.stem + ".dump.csv")
    air = ~r.truth["on_ground"].to_numpy(bool)
    rows = []
    for how, path, mapping in (
            ("export, its mapping", log.with_name(log.stem + ".ed112.csv"),
             log.with_name(log.stem + ".ed112.mapping.toml")),
            ("parameter dump, no mapping", dump, None)):
        fl = load_flight(path, mapping=mapping, sidecar=log.with_suffix(".meta.toml"),
                         gnss_use=GnssUse(withhold=True))
        j = run_method("joint", clean_flight(fl), ReconstructSettings())
        e = errors(j.track, r.truth, air)
        rows.append(f"| {scenario} | {airframe or '-'} | {seed} | "
                    f"{r.truth['t_s'].iloc[-1] / 60:.0f} | {how} | {e['rms_h_m']:.1f} | "
                    f"{e['nees_n']:.2f} / {e['nees_e']:.2f} |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=5)
    a = ap.parse_args()
    lines = ["| scenario | aircraft | seed | min | read as | recorder only: RMS h [m] | "
             "NEES n / e |", "|---|---|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as d, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for scenario, airframe in FLIGHTS:
            lines += one_flight(scenario, airframe, a.seed, Path(d))
    sys.stdout.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
