"""Per-flight manifests: what a batch needs to know to skip a flight already done.

A manifest ``<name>.manifest.json`` is written atomically in the output folder *after* the
flight's result, summary and store record, so its presence means all three are complete.  A
flight is up to date when its manifest's input fingerprint (SHA-256 of the log, its sidecar and
the sidecar's companion files) and settings key (SHA-256 of the reconstruction settings, output
format, store file and software version) equal the current ones and its outputs exist
(docs/batch.md, "Resuming").
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

from flightrecon import __version__
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.pipeline import ReconstructSettings, sha256_file

MANIFEST_VERSION = 1


def input_hashes(log: Path, sidecar: Path | None, mapping: Path | None = None
                 ) -> dict[str, str]:
    """``{resolved path: SHA-256}`` of the log, its sidecar, the sidecar's companion files and
    the batch's ``--mapping``."""
    paths = [log] + ([sidecar] if sidecar is not None else []) \
        + ([mapping] if mapping is not None else [])
    if sidecar is not None:
        from flightrecon.errors import FlightReconError
        from flightrecon.ingest.sidecar import load_sidecar

        try:
            paths += sorted(load_sidecar(sidecar).files.values())
        except FlightReconError:
            pass  # the sidecar's own hash changes when it is fixed; the flight fails meanwhile
    return {str(Path(p).resolve()): sha256_file(p) for p in paths}


def settings_key(settings: ReconstructSettings, fmt: str, store: Path | None,
                 gnss_use: GnssUse | None = None, frame_rate_hz: float | None = None) -> str:
    """SHA-256 of everything besides the inputs that changes a flight's outputs or store row
    (``gnss_use``: the batch's :class:`flightrecon.ingest.gnss_use.GnssUse`, ``None``: the
    logs' GNSS as recorded; ``frame_rate_hz``: the batch's ``--frame-rate``, ``None``: none)."""
    doc: dict[str, Any] = {"settings": asdict(settings), "format": fmt, "version": __version__,
                           "store": None if store is None else str(Path(store).resolve())}
    if gnss_use is not None and gnss_use != GnssUse():
        doc["gnss_use"] = gnss_use.as_dict()
    if frame_rate_hz is not None:
        doc["frame_rate_hz"] = float(frame_rate_hz)
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()


def read_manifest(path: Path) -> dict[str, Any] | None:
    """The manifest at ``path``; ``None`` when missing, unreadable or of another version (the
    flight is then simply redone)."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or doc.get("manifest_version") != MANIFEST_VERSION:
        return None
    return doc


def is_up_to_date(manifest: dict[str, Any] | None, hashes: dict[str, str], key: str,
                  outputs: list[Path]) -> bool:
    """True when ``manifest`` records these inputs and settings and every output exists."""
    return (manifest is not None and manifest.get("status") == "ok"
            and manifest.get("inputs") == hashes and manifest.get("settings_key") == key
            and all(p.is_file() for p in outputs))


def write_manifest(path: Path, doc: dict[str, Any]) -> Path:
    """Write ``doc`` (with :data:`MANIFEST_VERSION`) atomically as JSON."""
    from flightrecon.export.atomic import write_text_atomic
    from flightrecon.export.encode import to_json

    return write_text_atomic(path, to_json({**doc, "manifest_version": MANIFEST_VERSION}))
