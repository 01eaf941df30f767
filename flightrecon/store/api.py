"""The coefficient store: record, read, average, export and remove per-flight Sabziev fits.

Examples
--------
>>> from flightrecon.store import CoefficientStore            # doctest: +SKIP
>>> with CoefficientStore() as store:                          # doctest: +SKIP
...     store.record(fit)              # a FlightCoefficients
...     fm = store.fleet_mean("4K-AZ01")
...     fm.k, fm.sd, fm.n
"""

from __future__ import annotations

import csv
import json
import math
import os
import sqlite3
from collections.abc import Iterable
from pathlib import Path
from types import TracebackType

from flightrecon.errors import StoreError
from flightrecon.store import calibration as _cal
from flightrecon.store import stats as _stats
from flightrecon.store.calibration import (AircraftCalibration, FlightCalibration,
                                           SensorChange, SensorEstimate)
from flightrecon.store.db import DEFAULT_BUSY_TIMEOUT_S, connect, write_transaction
from flightrecon.store.identity import Identity, resolve_flight_id
from flightrecon.store.records import (AircraftStats, FleetMean, FlightCoefficients,
                                       now_utc_text, utc_text)
from flightrecon.store.schema import CALIBRATION_COLUMNS, FLIGHT_COLUMNS

_SELECT = "SELECT " + ", ".join(FLIGHT_COLUMNS) + " FROM flights"
_ORDER = " ORDER BY aircraft_id, flight_date_utc, flight_id"
_UPSERT = (
    "INSERT INTO flights (" + ", ".join(FLIGHT_COLUMNS) + ") VALUES ("
    + ", ".join("?" for _ in FLIGHT_COLUMNS)
    + ") ON CONFLICT (aircraft_id, flight_id) DO UPDATE SET "
    + ", ".join(f"{c} = excluded.{c}" for c in FLIGHT_COLUMNS[2:])
)

#: CSV columns of :meth:`CoefficientStore.export_csv` (units in the docs: k1, k3 [1/s], k2 [1/s^2])
CSV_COLUMNS: tuple[str, ...] = FLIGHT_COLUMNS

_CAL_SELECT = "SELECT id, " + ", ".join(CALIBRATION_COLUMNS) + " FROM calibration_flights"
_CAL_UPSERT = (
    "INSERT INTO calibration_flights (" + ", ".join(CALIBRATION_COLUMNS) + ") VALUES ("
    + ", ".join("?" for _ in CALIBRATION_COLUMNS)
    + ") ON CONFLICT (aircraft_id, flight_id) DO UPDATE SET "
    + ", ".join(f"{c} = excluded.{c}" for c in CALIBRATION_COLUMNS[2:])
)

#: CSV columns of :meth:`CoefficientStore.export_calibration_csv`: one row per flight and error
CALIBRATION_CSV_COLUMNS: tuple[str, ...] = (
    "aircraft_id", "flight_id", "flight_date_utc", "configuration", "sources", "duration_s",
    "tas_min_mps", "tas_max_mps", "alt_min_m", "alt_max_m", "converged", "log_sha256",
    "quantity", "value", "sd", "prior_mean", "prior_sd", "unit",
)


def _cal_to_row(c: FlightCalibration, stamp: str) -> tuple:
    try:
        settings = json.dumps(c.settings, sort_keys=True, allow_nan=False)
        hashes = json.dumps(c.input_hashes, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise StoreError(f"flight '{c.flight_id}': settings / input hashes are not plain JSON "
                         f"({exc})") from exc
    return (c.aircraft_id, c.flight_id, c.flight_date_utc, c.log_sha256, c.configuration,
            c.sources, c.duration_s, _null(c.tas_range_mps[0]), _null(c.tas_range_mps[1]),
            _null(c.alt_range_m[0]), _null(c.alt_range_m[1]), int(c.converged),
            c.software_version, settings, hashes, stamp)


def _cal_from_row(row: tuple, estimates: list[SensorEstimate]) -> FlightCalibration:
    (_, aircraft_id, flight_id, date, log_sha256, config, sources, duration, tlo, thi, alo,
     ahi, converged, version, settings, hashes, recorded) = row
    try:
        settings, hashes = json.loads(settings), json.loads(hashes)
    except ValueError as exc:
        raise StoreError(f"flight '{flight_id}' of aircraft '{aircraft_id}': settings / input "
                         f"hashes in the store are not valid JSON ({exc})") from exc
    return FlightCalibration(
        aircraft_id=aircraft_id, flight_id=flight_id, flight_date_utc=date,
        estimates=tuple(estimates), configuration=config, sources=sources, duration_s=duration,
        tas_range_mps=(tlo, thi), alt_range_m=(alo, ahi), converged=bool(converged),
        software_version=version, settings=settings, input_hashes=hashes,
        log_sha256=log_sha256, recorded_at_utc=recorded)


def _to_row(fc: FlightCoefficients) -> tuple:
    try:
        settings = json.dumps(fc.settings, sort_keys=True, allow_nan=False)
        hashes = json.dumps(fc.input_hashes, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise StoreError(f"flight '{fc.flight_id}': settings / input hashes are not plain JSON "
                         f"({exc})") from exc
    ac = fc.axis_converged or (fc.converged,) * 3
    return (fc.aircraft_id, fc.flight_id, fc.flight_date_utc, fc.duration_s,
            _null(fc.k1), _null(fc.k2), _null(fc.k3), fc.branch[0], fc.branch[1], fc.branch[2],
            int(fc.converged), int(ac[0]), int(ac[1]), int(ac[2]), _null(fc.residual_m),
            fc.iterations, fc.software_version, settings, hashes, fc.recorded_at_utc,
            fc.log_sha256, *(_null(x) for x in (fc.k_sd or (math.nan,) * 3)))


_STAMP = FLIGHT_COLUMNS.index("recorded_at_utc")


def _stamped(row: tuple, stamp: str) -> tuple:
    """A row of :func:`_to_row` with its ``recorded_at_utc`` set to ``stamp``."""
    return row[:_STAMP] + (stamp,) + row[_STAMP + 1:]


def _null(x: float) -> float | None:
    """NaN (unknown) as SQL NULL: SQLite would store NaN as NULL anyway, but say it."""
    return None if math.isnan(x) else x


def _from_row(row: tuple) -> FlightCoefficients:
    (aircraft_id, flight_id, date, duration, k1, k2, k3, b1, b2, b3, converged, c1, c2, c3,
     residual, iterations, version, settings, hashes, recorded, log_sha256, sd1, sd2, sd3) = row
    try:
        settings, hashes = json.loads(settings), json.loads(hashes)
    except ValueError as exc:
        raise StoreError(f"flight '{flight_id}' of aircraft '{aircraft_id}': settings / input "
                         f"hashes in the store are not valid JSON ({exc})") from exc
    return FlightCoefficients(
        aircraft_id=aircraft_id, flight_id=flight_id, flight_date_utc=date, duration_s=duration,
        k1=k1, k2=k2, k3=k3, branch=(b1, b2, b3), converged=bool(converged),
        residual_m=residual, iterations=iterations, software_version=version,
        settings=settings, input_hashes=hashes, axis_converged=(bool(c1), bool(c2), bool(c3)),
        recorded_at_utc=recorded, log_sha256=log_sha256, k_sd=(sd1, sd2, sd3))


class CoefficientStore:
    """A per-aircraft store of Sabziev coefficient fits in one SQLite file.

    Opening it creates the file on first use (default location:
    :func:`flightrecon.store.db.default_store_path`), upgrades an older schema, and refuses a
    file that is not a flightrecon store (:class:`~flightrecon.errors.StoreError`, file left
    unmodified).  Each call is its own transaction; several processes may write at once.

    Parameters
    ----------
    path : store file (``None``: ``$FLIGHTRECON_STORE`` or the per-user data folder)
    busy_timeout_s : how long to wait for another process's write lock [s]
    create : create a missing store (False: a missing store raises StoreError)

    Attributes
    ----------
    path : the store file
    journal_mode : ``"wal"``, or ``"delete"`` where the file system cannot do WAL
    notes : remarks for the user (e.g. the WAL fallback)
    """

    def __init__(self, path: str | os.PathLike | None = None, *,
                 busy_timeout_s: float = DEFAULT_BUSY_TIMEOUT_S, create: bool = True) -> None:
        self._con, self.path, self.journal_mode = connect(path, busy_timeout_s=busy_timeout_s,
                                                          create=create)
        self.notes: tuple[str, ...] = ()
        if self.journal_mode != "wal":
            self.notes = (f"journal mode {self.journal_mode}: the file system does not support "
                          "WAL; readers and the writer take turns",)

    # -- lifecycle ---------------------------------------------------------------------------
    def close(self) -> None:
        """Close the connection (idempotent)."""
        if self._con is not None:
            self._con.close()
            self._con = None

    def __enter__(self) -> CoefficientStore:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    @property
    def con(self) -> sqlite3.Connection:
        """The open connection (StoreError once closed)."""
        if self._con is None:
            raise StoreError("the coefficient store is closed", file=str(self.path))
        return self._con

    def _run(self, fn, *args):
        try:
            return fn(*args)
        except sqlite3.Error as exc:
            raise StoreError(f"coefficient store: {exc}", file=str(self.path)) from exc

    # -- writing -----------------------------------------------------------------------------
    def record(self, fit: FlightCoefficients) -> FlightCoefficients:
        """Insert ``fit``, or replace the row of the same (aircraft_id, flight_id).

        Returns the record as stored (``recorded_at_utc`` set to now).
        """
        return self.record_many([fit])[0]

    def record_many(self, fits: Iterable[FlightCoefficients]) -> list[FlightCoefficients]:
        """Record several fits in one transaction: all of them or, on any error, none."""
        def work() -> list[FlightCoefficients]:
            out = []
            with write_transaction(self.con) as con:
                stamp = now_utc_text()
                for fit in fits:
                    if not isinstance(fit, FlightCoefficients):
                        raise StoreError(f"expected FlightCoefficients, got {type(fit).__name__}")
                    row = _stamped(_to_row(fit), stamp)
                    con.execute(_UPSERT, row)
                    out.append(_from_row(row))
            return out
        return self._run(work)

    def remove(self, aircraft_id: str, flight_id: str | None = None) -> int:
        """Delete one flight, or every flight of the aircraft when ``flight_id`` is None.

        Both its Sabziev fit and its sensor calibration (with its estimates) are deleted.
        Returns the number of flights deleted (0 if there was nothing to delete).
        """
        def work() -> int:
            with write_transaction(self.con) as con:
                ids: set[str] = set()
                where, args = ("aircraft_id = ?", (aircraft_id,)) if flight_id is None else (
                    "aircraft_id = ? AND flight_id = ?", (aircraft_id, flight_id))
                for table in ("flights", "calibration_flights"):
                    ids.update(r[0] for r in con.execute(
                        f"SELECT flight_id FROM {table} WHERE {where}", args))
                    con.execute(f"DELETE FROM {table} WHERE {where}", args)
                return len(ids)
        return self._run(work)

    def record_flight(self, aircraft_id: str, flight_id: str | None, log_sha256: str, *,
                      fit: FlightCoefficients | None = None,
                      calibration: FlightCalibration | None = None) -> Identity:
        """Record one flight's Sabziev fit and / or sensor calibration under the record its log
        belongs to (:func:`flightrecon.store.identity.resolve_flight_id`), in one transaction.

        ``fit`` and ``calibration`` carry any flight id: the one resolved here replaces it.
        Returns the :class:`~flightrecon.store.identity.Identity` used.
        """
        from dataclasses import replace

        from flightrecon.store.records import check_sha256

        check_sha256(log_sha256)
        if log_sha256 is None:
            raise StoreError("record_flight needs the log's SHA-256")
        if fit is None and calibration is None:
            raise StoreError("nothing to record: neither a Sabziev fit nor a sensor calibration")
        for part in (fit, calibration):
            if part is not None and part.aircraft_id != aircraft_id:
                raise StoreError(f"record of aircraft '{part.aircraft_id}' given for aircraft "
                                 f"'{aircraft_id}'")

        def work() -> Identity:
            with write_transaction(self.con) as con:
                date = (fit or calibration).flight_date_utc  # type: ignore[union-attr]
                ident = resolve_flight_id(con, aircraft_id, flight_id, log_sha256, date)
                stamp = now_utc_text()
                if fit is not None:
                    f = replace(fit, flight_id=ident.flight_id, log_sha256=log_sha256)
                    con.execute(_UPSERT, _stamped(_to_row(f), stamp))
                if calibration is not None:
                    c = replace(calibration, flight_id=ident.flight_id, log_sha256=log_sha256)
                    self._write_calibration(con, c, stamp)
            return ident
        return self._run(work)

    @staticmethod
    def _write_calibration(con: sqlite3.Connection, c: FlightCalibration, stamp: str) -> None:
        con.execute(_CAL_UPSERT, _cal_to_row(c, stamp))
        ref = con.execute("SELECT id FROM calibration_flights WHERE aircraft_id = ? AND "
                          "flight_id = ?", (c.aircraft_id, c.flight_id)).fetchone()[0]
        con.execute("DELETE FROM sensor_estimates WHERE flight_ref = ?", (ref,))
        con.executemany(
            "INSERT INTO sensor_estimates (flight_ref, quantity, value, sd, prior_mean, "
            "prior_sd, unit) VALUES (?, ?, ?, ?, ?, ?, ?)",
            [(ref, e.quantity, e.value, e.sd, e.prior_mean, e.prior_sd, e.unit)
             for e in c.estimates])

    def record_calibration(self, cal: FlightCalibration) -> FlightCalibration:
        """Insert ``cal``, or replace the calibration of the same (aircraft_id, flight_id) and
        all its estimates (one transaction).  Returns it as stored."""
        if not isinstance(cal, FlightCalibration):
            raise StoreError(f"expected FlightCalibration, got {type(cal).__name__}")

        def work() -> FlightCalibration:
            with write_transaction(self.con) as con:
                stamp = now_utc_text()
                self._write_calibration(con, cal, stamp)
            return self.get_calibration(cal.aircraft_id, cal.flight_id)
        return self._run(work)

    def add_sensor_change(self, aircraft_id: str, change_utc: str, quantity: str = "*",
                          note: str = "") -> SensorChange:
        """Record that ``quantity``'s sensor (``"*"``: every sensor) of the aircraft was changed
        at ``change_utc``: flights before it no longer describe it after it."""
        when = utc_text(change_utc, "sensor change date")
        if not quantity or not isinstance(quantity, str):
            raise StoreError("sensor change: give a quantity or '*'")

        def work() -> SensorChange:
            with write_transaction(self.con) as con:
                con.execute("INSERT OR REPLACE INTO sensor_changes (aircraft_id, quantity, "
                            "change_utc, note) VALUES (?, ?, ?, ?)",
                            (aircraft_id, quantity, when, note))
            return SensorChange(aircraft_id, quantity, when, note)
        return self._run(work)

    def remove_sensor_change(self, aircraft_id: str, change_utc: str, quantity: str = "*") -> int:
        """Delete a recorded sensor change; returns the number removed."""
        when = utc_text(change_utc, "sensor change date")

        def work() -> int:
            with write_transaction(self.con) as con:
                return con.execute("DELETE FROM sensor_changes WHERE aircraft_id = ? AND "
                                   "quantity = ? AND change_utc = ?",
                                   (aircraft_id, quantity, when)).rowcount
        return self._run(work)

    def sensor_changes(self, aircraft_id: str) -> list[SensorChange]:
        """The aircraft's recorded sensor changes, by date."""
        return self._run(lambda: [SensorChange(*r) for r in self.con.execute(
            "SELECT aircraft_id, quantity, change_utc, note FROM sensor_changes WHERE "
            "aircraft_id = ? ORDER BY change_utc, quantity", (aircraft_id,))])

    def set_drift(self, aircraft_id: str, quantity: str, sd_per_sqrt_day: float | None) -> None:
        """Set the random-walk q [unit per sqrt(day)] of one error of the aircraft (``None``:
        estimate it from the flights again)."""
        def work() -> None:
            with write_transaction(self.con) as con:
                if sd_per_sqrt_day is None:
                    con.execute("DELETE FROM calibration_drift WHERE aircraft_id = ? AND "
                                "quantity = ?", (aircraft_id, quantity))
                    return
                q = float(sd_per_sqrt_day)
                if not (math.isfinite(q) and q >= 0):
                    raise StoreError(f"drift of {quantity}: must be a number >= 0, got {q}")
                con.execute("INSERT OR REPLACE INTO calibration_drift (aircraft_id, quantity, "
                            "sd_per_sqrt_day) VALUES (?, ?, ?)", (aircraft_id, quantity, q))
        self._run(work)

    def drift_settings(self, aircraft_id: str) -> dict[str, float]:
        """``{quantity: q}`` set for the aircraft."""
        return self._run(lambda: dict(self.con.execute(
            "SELECT quantity, sd_per_sqrt_day FROM calibration_drift WHERE aircraft_id = ?",
            (aircraft_id,)).fetchall()))

    # -- reading -----------------------------------------------------------------------------
    def list_calibrations(self, aircraft_id: str | None = None) -> list[FlightCalibration]:
        """Every recorded flight calibration (of one aircraft if given), by aircraft and date."""
        def work() -> list[FlightCalibration]:
            order = " ORDER BY aircraft_id, flight_date_utc, flight_id"
            if aircraft_id is None:
                rows = self.con.execute(_CAL_SELECT + order).fetchall()
            else:
                rows = self.con.execute(_CAL_SELECT + " WHERE aircraft_id = ?" + order,
                                        (aircraft_id,)).fetchall()
            est: dict[int, list[SensorEstimate]] = {}
            q = ("SELECT flight_ref, quantity, value, sd, prior_mean, prior_sd, unit FROM "
                 "sensor_estimates ORDER BY flight_ref, rowid")
            for ref, *e in self.con.execute(q):
                est.setdefault(ref, []).append(SensorEstimate(*e))
            return [_cal_from_row(r, est.get(r[0], [])) for r in rows]
        return self._run(work)

    def get_calibration(self, aircraft_id: str, flight_id: str) -> FlightCalibration:
        """The calibration of one flight; StoreError if it is not recorded."""
        for c in self.list_calibrations(aircraft_id):
            if c.flight_id == flight_id:
                return c
        raise StoreError(f"no sensor calibration of flight '{flight_id}' of aircraft "
                         f"'{aircraft_id}' in the store", file=str(self.path))

    def calibration(self, aircraft_id: str, at_utc: str | None = None, *,
                    configuration: str | None = None) -> AircraftCalibration:
        """The aircraft's fused sensor calibration at ``at_utc`` (default: its latest flight),
        with its sensor changes and drift settings (rule: :mod:`flightrecon.store.calibration`);
        StoreError if it has no calibration recorded."""
        records = self.list_calibrations(aircraft_id)
        if not records:
            raise StoreError(f"no sensor calibration recorded for aircraft '{aircraft_id}'",
                             file=str(self.path))
        return _cal.aircraft_calibration(
            aircraft_id, records, at_utc, changes=self.sensor_changes(aircraft_id),
            drift=self.drift_settings(aircraft_id), configuration=configuration)

    def export_calibration_csv(self, path: str | os.PathLike,
                               aircraft_id: str | None = None) -> int:
        """Write the recorded sensor estimates to a CSV file, atomically: one row per flight
        and error (:data:`CALIBRATION_CSV_COLUMNS`).  Returns the number of rows."""
        from flightrecon.export.atomic import atomic_path

        n = 0
        cals = self.list_calibrations(aircraft_id)
        with atomic_path(Path(path)) as tmp:
            with open(tmp, "w", newline="", encoding="utf-8") as fh:
                w = csv.writer(fh)
                w.writerow(CALIBRATION_CSV_COLUMNS)
                for c in cals:
                    head = [c.aircraft_id, c.flight_id, c.flight_date_utc, c.configuration,
                            c.sources, c.duration_s, *c.tas_range_mps, *c.alt_range_m,
                            int(c.converged), c.log_sha256 or ""]
                    for e in c.estimates:
                        row = head + [e.quantity, e.value, e.sd, e.prior_mean, e.prior_sd, e.unit]
                        w.writerow(["" if isinstance(v, float) and math.isnan(v)
                                    else (repr(v) if isinstance(v, float) else v) for v in row])
                        n += 1
        return n

    def list_flights(self, aircraft_id: str | None = None) -> list[FlightCoefficients]:
        """Every recorded fit (of one aircraft if given), by aircraft, date, flight id."""
        def work() -> list[FlightCoefficients]:
            if aircraft_id is None:
                rows = self.con.execute(_SELECT + _ORDER).fetchall()
            else:
                rows = self.con.execute(_SELECT + " WHERE aircraft_id = ?" + _ORDER,
                                        (aircraft_id,)).fetchall()
            return [_from_row(r) for r in rows]
        return self._run(work)

    def aircraft(self) -> list[tuple[str, int]]:
        """``[(aircraft_id, number of flights), ...]`` sorted by aircraft id."""
        return self._run(lambda: [(a, int(n)) for a, n in self.con.execute(
            "SELECT aircraft_id, count(*) FROM flights GROUP BY aircraft_id ORDER BY aircraft_id")])

    def get(self, aircraft_id: str, flight_id: str) -> FlightCoefficients:
        """The fit of one flight; StoreError if it is not recorded."""
        rows = self._run(lambda: self.con.execute(
            _SELECT + " WHERE aircraft_id = ? AND flight_id = ?", (aircraft_id, flight_id)
        ).fetchall())
        if not rows:
            raise StoreError(f"no flight '{flight_id}' of aircraft '{aircraft_id}' in the store",
                             file=str(self.path))
        return _from_row(rows[0])

    def flight_id_of(self, aircraft_id: str, log_sha256: str) -> str | None:
        """The flight id under which the log with this SHA-256 is recorded for the aircraft
        (``None`` if it is not; identity rule 1 of :mod:`flightrecon.store.identity`)."""
        from flightrecon.store.identity import identity_rows, same_identity

        for fid, h, hashes in self._run(lambda: identity_rows(self.con, aircraft_id)):
            if same_identity(h, hashes, log_sha256):
                return fid
        return None

    def count(self) -> int:
        """Number of recorded fits."""
        return int(self._run(
            lambda: self.con.execute("SELECT count(*) FROM flights").fetchone()[0]))

    # -- statistics --------------------------------------------------------------------------
    def aircraft_stats(self, aircraft_id: str) -> AircraftStats:
        """Per-axis count, mean, median, std and drift of one aircraft's fits
        (rule: :mod:`flightrecon.store.stats`); StoreError if the aircraft has no flights."""
        records = self.list_flights(aircraft_id)
        if not records:
            raise StoreError(f"no flights of aircraft '{aircraft_id}' in the store",
                             file=str(self.path))
        return _stats.aircraft_stats(aircraft_id, records)

    def fleet_mean(self, aircraft_id: str, min_flights: int = 1, *,
                   allow_missing: bool = False) -> FleetMean:
        """Fleet coefficients, their flight-to-flight spread and counts, for the initial-value
        mode (see :func:`flightrecon.store.stats.fleet_mean`)."""
        return _stats.fleet_mean(self.aircraft_stats(aircraft_id), min_flights=min_flights,
                                 allow_missing=allow_missing)

    # -- export ------------------------------------------------------------------------------
    def export_csv(self, path: str | os.PathLike, aircraft_id: str | None = None) -> int:
        """Write the fits (of one aircraft if given) to a CSV file, atomically.

        Columns: :data:`CSV_COLUMNS`; booleans as 0/1, a missing residual or iteration count as
        an empty cell, settings and input hashes as JSON text.  Returns the number of rows.
        """
        from flightrecon.export.atomic import atomic_path

        records = self.list_flights(aircraft_id)
        with atomic_path(Path(path)) as tmp:
            with open(tmp, "w", newline="", encoding="utf-8") as fh:
                w = csv.writer(fh)
                w.writerow(CSV_COLUMNS)
                for r in records:
                    row = list(_to_row(r))
                    row = ["" if v is None else (repr(v) if isinstance(v, float) else v)
                           for v in row]
                    w.writerow(row)
        return len(records)
