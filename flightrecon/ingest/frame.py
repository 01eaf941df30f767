"""The flight's table from the merged rows: derived channels (TAS from CAS/IAS, true from
magnetic angles, ``n_long_g`` from airspeed and pitch), values checked at the door (ranges,
polarity, GNSS quality, physics), angles wrapped, provenance columns ``row`` and ``src_file``
(docs/ingest.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.ingest.derive import derive_n_lat, derive_n_long, derive_tas, true_from_magnetic
from flightrecon.ingest.door import DeclaredUnit, DoorCheck, DoorRefusal
from flightrecon.ingest.gnss_quality import apply_gnss_quality
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.ingest.mapping import Mapping
from flightrecon.ingest.mapping_apply import mapping_location
from flightrecon.ingest.physics import door_checks
from flightrecon.ingest.sources import Sources
from flightrecon.ingest.polarity import check_polarity
from flightrecon.ingest.validate import Provenance, check_values
from flightrecon.schema import BY_NAME, CHANNELS
from flightrecon.types import FlightMeta


def derived_channels(src: Sources, meta: FlightMeta, log: Path, warns: list[str],
                     notes: list[str]) -> dict[str, np.ndarray]:
    """The channels on the merged rows, with TAS from CAS/IAS and true from magnetic angles."""
    rows = src.rows
    values = dict(rows.values)
    for ch, kind in src.mt.derived.items():
        values[ch], w = derive_tas(rows.t, values, kind, str(log))
        warns += w
        notes.append(f"{ch} computed from {kind}_mps, sat_degc and baro_alt_m (ISA, "
                     "compressible)")
    for ch, (f, col) in src.magnetic.items():
        values[ch], n = true_from_magnetic(rows.t, values[ch], values, meta, f, col)
        notes += n
    if src.derive_long:
        values["n_long_g"], note = derive_n_long(rows.t, values, str(log))
        notes.append(note)
        warns.append(note)
    if src.derive_lat:
        values["n_lat_g"], note = derive_n_lat(rows.t, values, str(log))
        notes.append(note)
        warns.append(note)
    return values


def declared_units(mp: Mapping | None, src: Sources) -> dict[str, DeclaredUnit]:
    """The unit each mapped channel's column is read in, and whether the mapping wrote it
    (the user's word: it wins over a doubt of the door's physics, and over a certain
    contradiction only when confirmed; docs/door.md), with the mapping's line.  A true
    airspeed computed from CAS or IAS is judged in its source's unit."""
    out: dict[str, DeclaredUnit] = {}
    for m, table in ((mp, "channels"), (getattr(mp, "gnss", None), "gnss.channels"),
                     (getattr(mp, "radar", None), "radar.channels")):
        if m is None:
            continue
        for spec in m.channels:
            if spec.unit is not None:
                key = "unit" if spec.unit_declared else "column"
                out[spec.channel] = DeclaredUnit(
                    spec.unit.name, spec.unit_declared, f"{m.file} [{table}.{spec.channel}]",
                    mapping_location(m.file, f"{table}.{spec.channel}", key),
                    spec.unit_confirmed)
    kind = src.mt.derived.get("tas_mps")
    if kind is not None and f"{kind}_mps" in out:
        out["tas_mps"] = out[f"{kind}_mps"]
    return out


def validated_frame(src: Sources, values: dict[str, np.ndarray], warns: list[str],
                    notes: list[str], declared: dict[str, DeclaredUnit] | None = None,
                    door: list[DoorCheck] | None = None, use: GnssUse | None = None,
                    gnss_rec: dict[str, Any] | None = None) -> tuple[pd.DataFrame, list[Any]]:
    """The flight's table: values checked (ranges, polarity, GNSS quality and the analyst's
    GNSS options ``use``, physics), angles wrapped, empty channels dropped, provenance columns
    ``row`` and ``src_file``; with the repairs made.  The door's checks are appended to
    ``door``, what the GNSS options did and the rounding added to ``gnss_rec``."""
    rows = src.rows
    cols = _own_columns({"t_s": rows.t, **{c.name: values[c.name] for c in CHANNELS
                                           if c.name in values}})
    # one block per column (copy=False): no 100 MB consolidation copy for a 10-hour log
    data = pd.DataFrame(cols, copy=False)
    prov = Provenance(files=tuple(src.files), src_file=rows.src_file, row=rows.row,
                      source_column=tuple(src.source_cols))
    door = door if door is not None else []
    w, repairs = check_values(data, prov, rows.nan_text)
    warns += w
    door.append(_summary_check("values in range", w, f"{len(repairs)} value(s) repaired"))
    for r in {r.channel for r in repairs}:
        cols[r] = data[r].to_numpy()
    w = check_polarity(data, prov)
    warns += w
    door.append(_summary_check("load-factor polarity", w, "n_norm_g, n_long_g and the turns' "
                               "n_lat_g have the schema's signs"))
    w, rq, nq, rec = apply_gnss_quality(cols, rows.t, prov, use)
    if gnss_rec is not None:
        gnss_rec.update(rec)
    warns += w
    repairs += rq
    notes += nq
    try:                                 # units and time base against physics
        w, checks = door_checks(data, prov, declared)
    except DoorRefusal as exc:
        door += exc.checks
        raise
    warns += w
    door += checks
    for name in list(cols):
        ch = BY_NAME.get(name)
        if ch is not None and ch.angle:
            # wrapped on the sampled rows only: numpy's floating modulo is about 100 times
            # slower on NaN (the unsampled rows of a multi-rate log) than on numbers
            v = cols[name].copy()
            ok = ~np.isnan(v)
            v[ok] = np.mod(v[ok], 360.0)
            cols[name] = v
        if name != "t_s" and np.isnan(cols[name]).all():
            del cols[name]
    cols["row"] = np.array(rows.row, copy=True)
    cols["src_file"] = rows.src_file.astype(np.int8)
    return pd.DataFrame(cols, copy=False), repairs


def _summary_check(check: str, warns: list[str], ok_text: str) -> DoorCheck:
    """A door record for a validation step that raises on certainty and warns otherwise."""
    if warns:
        return DoorCheck(check, "-", "warned", float(len(warns)), "; ".join(warns))
    return DoorCheck(check, "-", "passed", None, ok_text)


def _own_columns(cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The columns as writeable arrays that share memory with no other column (a copy
    only where needed: a read-only Arrow buffer, a column mapped twice), so the table can be
    built without a copy and still be modified column by column by its users."""
    out: dict[str, np.ndarray] = {}
    for k, v in cols.items():
        v = np.asarray(v)
        if not v.flags.writeable or any(np.may_share_memory(v, o) for o in out.values()):
            v = v.copy()
        out[k] = v
    return out
