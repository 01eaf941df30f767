"""The aircraft of a Garmin export taken from what it records (issue #49 item 7): a folder of
exports through ``batch`` builds the per-aircraft coefficient store with no sidecar (before:
"no: no aircraft id" on every flight)."""

from __future__ import annotations

import csv
import warnings
from pathlib import Path

import pytest

from flightrecon.batch import batch, open_client
from flightrecon.ingest.garmin import garmin_identity
from flightrecon.sim.glass_cockpit import glass_cockpit_export, glass_cockpit_text
from flightrecon.sim.scenarios import simulate_fleet
from flightrecon.store import CoefficientStore


def test_identity_from_the_information_line():
    g1000 = {"airframe_name": "Cessna 172S", "system_id": "24B6FD7AC", "log_version": "1.00"}
    assert garmin_identity(g1000) == {"aircraft_id": "24B6FD7AC", "id_from": "system_id",
                                      "system_id": "24B6FD7AC", "aircraft_type": "Cessna 172S"}
    g3x = {"product": "GDU 460", "aircraft_ident": "N123AB", "system_id": "6000ABCD01234"}
    ident = garmin_identity(g3x)
    assert ident["aircraft_id"] == "N123AB" and ident["registration"] == "N123AB"
    assert ident["system_id"] == "6000ABCD01234" and "aircraft_type" not in ident
    assert garmin_identity({"log_version": "1.00"}) == {}


def test_batch_over_garmin_exports_records_each_aircraft(tmp_path):
    """Two aircraft, two circuits each, written as G1000 exports with their avionics'
    system id and no sidecar: every flight is stored under its aircraft."""
    d = tmp_path / "exports"
    d.mkdir()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for a, sid in (("A1", "24B0000AA"), ("B2", "25B0000BB")):
            for r in simulate_fleet(a, 2, seed=3, scenario="circuit"):
                ex = glass_cockpit_export(r.log, r.truth, r.meta)
                (d / f"{a}_{r.meta.flight_id}.csv").write_text(
                    glass_cockpit_text(ex, airframe_name="Cessna 172S", system_id=sid))
    store = tmp_path / "fleet.sqlite"
    with open_client(workers=2) as client:
        res = batch([d], tmp_path / "out", client=client, store=store)
    rows = list(csv.DictReader(open(res.summary_csv, newline="", encoding="utf-8")))
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows), rows
    assert {r["aircraft_id"] for r in rows} == {"24B0000AA", "25B0000BB"}
    assert all(r["stored"].startswith("yes") for r in rows), [r["stored"] for r in rows]
    with CoefficientStore(store, create=False) as db:
        per = {a: len(db.list_calibrations(a)) for a in ("24B0000AA", "25B0000BB")}
    assert per == {"24B0000AA": 2, "25B0000BB": 2}
    assert {r["aircraft_id"] for r in res.averages} <= {"24B0000AA", "25B0000BB"}


@pytest.mark.parametrize("sidecar_id", ["F-GABC"])
def test_a_sidecar_names_the_aircraft_over_the_export(tmp_path, sidecar_id):
    from flightrecon.ingest import load_flight

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = simulate_fleet("A1", 1, seed=3, scenario="circuit")[0]
        p = tmp_path / "x.csv"
        p.write_text(glass_cockpit_text(glass_cockpit_export(r.log, r.truth, r.meta),
                                        system_id="24B0000AA"))
        (tmp_path / "x.meta.toml").write_text(f'[flight]\naircraft_id = "{sidecar_id}"\n')
        fl = load_flight(p)
    assert fl.meta.aircraft_id == sidecar_id
    assert fl.meta.ingest.recorder["system_id"] == "24B0000AA"
    assert Path(fl.sources[0]) == p
