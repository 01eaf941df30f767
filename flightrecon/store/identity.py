"""Flight identity in the store: which record a flight's log belongs to (docs/store.md,
"Flight identity").

A record is one flight of one aircraft, keyed by ``(aircraft_id, flight_id)``; its content
identity is the SHA-256 of its log (``log_sha256``).  The rule, applied under the store's write
lock so that concurrent writers agree:

1. the same log already recorded for this aircraft (same ``log_sha256``, or, for a row upgraded
   from a v2 store without one, the hash among the row's input hashes): that record is updated,
   whatever flight id the sidecar now gives;
2. no flight id: the id is derived from the content, the first :data:`DERIVED_ID_CHARS` hex
   digits of the log's SHA-256;
3. the flight id is already recorded for another log (or for a row whose content is unknown):
   the two are different flights that share a name (a sidecar copied from another flight, a
   flight number flown every day), never merged: the new one is recorded as
   ``<flight_id>~<first 8 hex digits of its SHA-256>`` and the result says so;
4. otherwise the flight id as given.

Different bytes are different logs: the same flight exported once as CSV and once as Parquet
gives two records.
"""

from __future__ import annotations

import json
import sqlite3
from dataclasses import dataclass

#: hex digits of the log's SHA-256 in a derived flight id
DERIVED_ID_CHARS = 16
#: separator of a flight id and the hash suffix that disambiguates it
SUFFIX_SEP = "~"


@dataclass(frozen=True)
class Identity:
    """The record a flight's log is stored under.

    Attributes
    ----------
    flight_id : the key used
    action : ``"new"``, ``"updated"`` (same log recorded before), ``"derived"`` (no flight id
        given) or ``"disambiguated"`` (the given id belongs to another log)
    note : one sentence for the user ("" for ``new``)
    requested : the flight id asked for (``None`` when none was given)
    """

    flight_id: str
    action: str
    note: str
    requested: str | None


def identity_rows(con: sqlite3.Connection, aircraft_id: str, with_date: bool = False) -> list[tuple]:
    out = []
    for table in ("flights", "calibration_flights"):
        for fid, h, hashes, date in con.execute(
                f"SELECT flight_id, log_sha256, input_hashes_json, flight_date_utc FROM {table} "
                "WHERE aircraft_id = ?", (aircraft_id,)):
            try:
                hv = json.loads(hashes)
            except ValueError:
                hv = {}
            row = (fid, h, hv if isinstance(hv, dict) else {})
            out.append(row + (date,) if with_date else row)
    return out


def same_log(h: str | None, hashes: dict, log_sha256: str) -> bool:
    if h is not None:
        return h == log_sha256
    return log_sha256 in {str(v) for v in hashes.values()}


def resolve_flight_id(con: sqlite3.Connection, aircraft_id: str, flight_id: str | None,
                      log_sha256: str, flight_date_utc: str | None = None) -> Identity:
    """The record of the log with SHA-256 ``log_sha256`` (rule: module docstring).  Call it
    inside the write transaction that records the flight.  With ``flight_date_utc``, a
    disambiguated flight whose take-off time equals the other record's is noted as a possible
    duplicate (the same flight in another file format counts twice in the averages)."""
    dated = identity_rows(con, aircraft_id, with_date=True)
    rows = [r[:3] for r in dated]
    for fid, h, hashes in rows:
        if same_log(h, hashes, log_sha256):
            note = "" if fid == flight_id else (
                f"this log is recorded as flight '{fid}'" + (
                    f" (the metadata now say '{flight_id}')" if flight_id else ""))
            return Identity(fid, "updated", note, flight_id)
    if not flight_id:
        fid = log_sha256[:DERIVED_ID_CHARS]
        return Identity(fid, "derived", f"no flight id given: '{fid}' derived from the log's "
                        "SHA-256", None)
    taken = {fid for fid, _, _ in rows}
    if flight_id not in taken:
        return Identity(flight_id, "new", "", flight_id)
    for n in (8, 16, 64):
        fid = f"{flight_id}{SUFFIX_SEP}{log_sha256[:n]}"
        if fid not in taken:
            break
    note = (f"flight id '{flight_id}' of aircraft '{aircraft_id}' is already recorded for "
            f"another log; this log is recorded as '{fid}'")
    if flight_date_utc is not None and any(r[0] == flight_id and r[3] == flight_date_utc
                                           for r in dated):
        note += (f" (same take-off time {flight_date_utc} as '{flight_id}': if it is the same "
                 "flight in another file, remove one with flightrecon coeffs remove, or it "
                 "counts twice in the averages)")
    return Identity(fid, "disambiguated", note, flight_id)
