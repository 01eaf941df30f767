"""The KML replay needs no network (issue 53): it linked the aircraft's icon on a web server,
so a replay opened offline showed a broken image.  Nothing in the document may point outside
it: no ``href`` (Icon, Link, NetworkLink, overlays, models), no URL in any text or attribute
(the namespace declarations are names, not fetched), every ``styleUrl`` a style of the
document itself."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
from _cli import run_cli

from flightrecon.events import Event, events_table
from flightrecon.export.replay import write_kml

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
KML = "{http://www.opengis.net/kml/2.2}"
EPOCH = "2026-01-01T10:00:00Z"


def offline_problems(path: Path) -> list[str]:
    """What in the KML at ``path`` would need a network or another file."""
    root = ET.parse(path).getroot()
    ids = {el.get("id") for el in root.iter() if el.get("id")}
    problems = []
    for el in root.iter():
        tag = el.tag.split("}")[-1]
        if tag in ("href", "Link", "NetworkLink", "Model", "GroundOverlay",
                   "ScreenOverlay", "PhotoOverlay"):
            problems.append(f"<{tag}> {el.text or ''}".strip())
        texts = [el.text or "", *el.attrib.values()]
        problems += [f"<{tag}> {t.strip()[:80]}" for t in texts if "://" in t]
        if tag == "styleUrl" and (not (el.text or "").startswith("#")
                                  or el.text[1:] not in ids):
            problems.append(f"<styleUrl> {el.text}: not a style of this document")
    return problems


def _turn(n: int = 200, dt: float = 0.5) -> pd.DataFrame:
    """A level turn at 100 m/s, 3 deg/s, 1000 m ellipsoidal height."""
    t = np.arange(n) * dt
    psi = np.radians(3.0) * t
    r = 100.0 / np.radians(3.0)
    north, east = r * np.sin(psi), r * (1 - np.cos(psi))
    return pd.DataFrame({"t_s": t, "lat_deg": 40.0 + north / 111_000.0,
                         "lon_deg": 50.0 + east / (111_000.0 * np.cos(np.radians(40.0))),
                         "alt_m": 1000.0 + 0 * t, "vn_mps": 100.0 * np.cos(psi),
                         "ve_mps": 100.0 * np.sin(psi), "vu_mps": 0 * t})


def test_every_style_and_mark_needs_no_network(tmp_path):
    """A replay with the aircraft and one event of each severity: every placemark's style is
    in the document, and nothing points outside it."""
    ev = [Event("liftoff", 10.0, "lift-off", "lift-off"),
          Event("exceedance", 30.0, "bank +50 deg", "bank", end_t_s=35.0, severity="alert"),
          Event("gap", 50.0, "GNSS gap", "gap", end_t_s=60.0, severity="caution")]
    meta = {"flight": {"flight_id": "F1", "epoch_utc": EPOCH, "geoid_undulation_m": -22.0},
            "events": events_table(ev, EPOCH)}
    p = write_kml(tmp_path / "t.kml", _turn(), "F1", metadata=meta)
    assert offline_problems(p) == []
    root = ET.parse(p).getroot()
    used = {u.text for u in root.iter(f"{KML}styleUrl")}
    assert {"#line", "#aircraft", "#event-info", "#event-alert", "#event-caution"} <= used


def test_reconstructed_kml_needs_no_network(tmp_path):
    """``reconstruct ... -o x.kml`` on the shipped circuit: the replay and its events are
    there, and nothing in it points outside it."""
    out = tmp_path / "circuit.kml"
    assert run_cli(["reconstruct", str(SAMPLES / "circuit.parquet"), "--methods", "joint",
                    "-o", str(out)]) == 0
    root = ET.parse(out).getroot()
    assert root.find(".//{http://www.google.com/kml/ext/2.2}Track") is not None
    assert offline_problems(out) == []
