"""The summary document of a reconstruction (JSON-serialisable, versioned)."""

from __future__ import annotations

import hashlib
import platform
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import pandas as pd

from flightrecon import __version__
from flightrecon.pipeline.registry import DEFAULT_PRIORITY, ReconstructSettings
from flightrecon.types import CleanFlight, declared_metadata

SUMMARY_SCHEMA_VERSION = 1


def sha256_file(path: str | Path, chunk: int = 1 << 20) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while True:
            b = fh.read(chunk)
            if not b:
                break
            h.update(b)
    return h.hexdigest()


def build_summary(clean: CleanFlight, settings: ReconstructSettings, status: dict[str, Any], *,
                  inputs: Sequence[str | Path] = (), warnings_: Sequence[str] = ()
                  ) -> dict[str, Any]:
    """The summary document (JSON-serialisable) with its schema version."""
    ph = clean.phases
    return {
        "schema_version": SUMMARY_SCHEMA_VERSION,
        "software": {"name": "flightrecon", "version": __version__,
                     "python": platform.python_version()},
        "inputs": [{"path": str(p), "sha256": sha256_file(p)} for p in inputs if Path(p).is_file()],
        "flight": declared_metadata(clean.meta),
        "settings": settings.to_dict(),
        "grid": {"rate_hz": clean.rate_hz, "samples": len(clean.grid),
                 "t0_s": float(clean.grid["t_s"].iloc[0]) if len(clean.grid) else None,
                 "t1_s": float(clean.grid["t_s"].iloc[-1]) if len(clean.grid) else None},
        "measurements": {"gnss_fixes": len(clean.gnss), "radar_plots": len(clean.radar),
                         # the analyst's GNSS options and the rounding added (ingest/gnss_use.py)
                         "gnss_use": dict(clean.meta.ingest.gnss_use)},
        # every check of the door with its figure and verdict (docs/door.md)
        "door": list(clean.meta.ingest.door),
        "phases": None if ph is None else asdict(ph),
        "cleaning": {"actions": len(clean.report), "report": list(clean.report)[:200]},
        "output": {
            "frame": ("east-north-up tangent plane at the departure airfield (metres)"
                      if clean.meta.departure is not None else
                      "east-north-up tangent plane at the first position fix (meta origin; "
                      "no departure airfield given) (metres)"),
            "alt_datum": "WGS-84 ellipsoidal height (alt_m)",
            "default_source_priority": list(DEFAULT_PRIORITY),
        },
        "methods": status,
        "warnings": list(warnings_),
    }


def result_choice(track: pd.DataFrame, status: dict[str, Any],
                  order: Sequence[str] | None = None,
                  evidence: dict[str, Any] | None = None) -> dict[str, Any]:
    """Which method the default (unprefixed) result comes from, and why, for the summary.

    ``order``: the order in which the healthy tracks fed the default, chosen by the evidence
    of the flight (:func:`flightrecon.pipeline.evidence.choose_order`; default the fixed
    :data:`DEFAULT_PRIORITY`); ``evidence``: per healthy method its rank, why, and its checks
    (:func:`flightrecon.pipeline.evidence.evidence_summary`).

    Returns
    -------
    dict
        ``method``: the source of most samples (``None`` when no healthy method covers any);
        ``fractions``: fraction of the grid samples from each source; ``why``: a sentence;
        ``not_used``: for each method ahead of it in the priority, why it is not the source;
        ``order`` and ``evidence`` as given.
    """
    priority = list(order) if order is not None else list(DEFAULT_PRIORITY)
    n = len(track)
    counts = track["source"].value_counts(dropna=True)  # Arrow strings: no Python loop
    fractions = {str(k): float(c) / n for k, c in counts.items() if k and n}
    method = max(fractions, key=lambda k: fractions[k]) if fractions else None
    ev = evidence or {}
    not_used = {}
    for m in DEFAULT_PRIORITY:
        if m == method:
            break
        st = status.get(m, {})
        if m in ev and m not in priority:   # healthy, refuted by a held-out point
            not_used[m] = f"{st.get('status', 'not run')}, {ev[m]['why']}"
            continue
        if m in priority and priority.index(m) > (priority.index(method)
                                                  if method in priority else -1):
            not_used[m] = f"{st.get('status')}, after it: {ev.get(m, {}).get('why', '')}"
            continue
        not_used[m] = f"{st.get('status', 'not run')}" + (
            f": {st['reason']}" if st.get("reason") else "")
    if method is None:
        why = ("no healthy method covers any sample: the default columns are empty; "
               + "; ".join(f"{m} {r}" for m, r in not_used.items()))
    else:
        share = fractions[method]
        why = (f"{method} is the first of the healthy tracks in the order "
               f"{' > '.join(priority)}" + (f" and gives {100 * share:.1f} % of the samples"
                                            if share < 0.999 else ""))
        if method in ev:
            why += f" ({ev[method]['why']})"
        if not_used:
            why += "; the others: " + "; ".join(f"{m} {r}" for m, r in not_used.items())
    out: dict[str, Any] = {"method": method, "fractions": fractions, "why": why,
                           "not_used": not_used}
    if order is not None:
        out["order"] = priority
        out["evidence"] = ev
    return out
