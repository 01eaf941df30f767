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


def _rows(con: sqlite3.Connection, aircraft_id: str) -> list[tuple[str, str | None, dict]]:
    out = []
    for table in ("flights", "calibration_flights"):
        for fid, h, hashes in con.execute(
                f"SELECT flight_id, log_sha256, input_hashes_json FROM {table} "
                "WHERE aircraft_id = ?", (aircraft_id,)):
            try:
                hv = json.loads(hashes)
            except ValueError:
                hv = {}
            out.append((fid, h, hv if isinstance(hv, dict) else {}))
    return out


def _same(h: str | None, hashes: dict, log_sha256: str) -> bool:
    if h is not None:
        return h == log_sha256
    return log_sha256 in {str(v) for v in hashes.values()}


def resolve_flight_id(con: sqlite3.Connection, aircraft_id: str, flight_id: str | None,
                      log_sha256: str) -> Identity:
    """The record of the log with SHA-256 ``log_sha256`` (rule: module docstring).  Call it
    inside the write transaction that records the flight."""
    rows = _rows(con, aircraft_id)
    for fid, h, hashes in rows:
        if _same(h, hashes, log_sha256):
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
    return Identity(fid, "disambiguated",
                    f"flight id '{flight_id}' of aircraft '{aircraft_id}' is already recorded for "
                    f"another log; this log is recorded as '{fid}'", flight_id)
