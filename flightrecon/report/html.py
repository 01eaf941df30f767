"""A self-contained HTML report: figures embedded as data URIs, no external resources."""

from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import pandas as pd

from flightrecon.export.atomic import atomic_path
from flightrecon.report.plots import make_figures


def _png_bytes(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def _method_table(summary: dict[str, Any]) -> str:
    rows = []
    for name, st in (summary.get("methods") or {}).items():
        if not isinstance(st, dict):
            continue
        keys = {k: v for k, v in st.items()
                if k not in ("history", "report") and isinstance(v, (str, int, float, bool))}
        rows.append(f"<tr><th>{html.escape(name)}</th><td><code>"
                    f"{html.escape(json.dumps(keys, default=str)[:1500])}</code></td></tr>")
    return "<table>" + "".join(rows) + "</table>"


def _fleet_section(summary: dict[str, Any]) -> str:
    """Which fleet calibration and coefficients the reconstruction used (``--use-fleet-
    coefficients``), from how many flights; empty when none was used."""
    fc = summary.get("fleet_coefficients")
    if not fc:
        return ""
    e = html.escape
    cal = fc.get("calibration")
    out = ["<h2>Fleet calibration</h2>"]
    if cal:
        rows = "".join(
            f"<tr><td>{e(n)}</td><td>{q['mean']:.4g}</td><td>{q['sd']:.3g}</td><td>{q['n']}</td>"
            f"<td>{'yes' if q['applied'] else 'no'}</td></tr>"
            for n, q in cal["errors"].items())
        out.append(f"<p>Sensor calibration of aircraft <b>{e(str(fc['aircraft_id']))}</b> at "
                   f"{e(str(cal['at_utc']))} from <b>{cal['n_flights']}</b> flight(s) "
                   f"({e(', '.join(cal['flights']))}) of store <code>{e(str(fc['store']))}</code>"
                   "; the errors marked applied were the joint smoother's priors.</p>"
                   "<table><tr><th>error</th><th>mean</th><th>sd</th><th>flights</th>"
                   f"<th>applied</th></tr>{rows}</table>")
    else:
        out.append(f"<p>No sensor calibration: {e(str(fc.get('calibration_missing')))}</p>")
    if fc.get("k") is not None:
        out.append(f"<p>Sabziev fleet-mean k = {e(str(fc['k']))} (fits per axis "
                   f"{e(str(fc['flights']))}).</p>")
    return "".join(out)


def write_report(folder: str | Path, track: pd.DataFrame, summary: dict[str, Any],
                 truth: pd.DataFrame | None = None, title: str = "flightrecon report") -> Path:
    """Write ``report.html`` and one PNG per figure into ``folder`` (created if needed).

    Returns the path of the HTML page.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    figs = make_figures(track, summary, truth)
    parts = []
    for name, fig in figs.items():
        png = _png_bytes(fig)
        with atomic_path(folder / f"{name}.png") as tmp:
            tmp.write_bytes(png)
        uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
        parts.append(f'<figure><img alt="{name}" src="{uri}"><figcaption>{name.replace("_", " ")}'
                     "</figcaption></figure>")
    fl = summary.get("flight") or {}
    warn = "".join(f"<li>{html.escape(str(w))}</li>" for w in summary.get("warnings") or [])
    inputs = "".join(f"<li><code>{html.escape(str(i.get('path')))}</code> sha256 "
                     f"<code>{html.escape(str(i.get('sha256')))}</code></li>"
                     for i in summary.get("inputs") or [])
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:auto;padding:1em}}
img{{max-width:100%}} table{{border-collapse:collapse}} td,th{{border:1px solid #ccc;padding:4px;
text-align:left;vertical-align:top}} code{{font-size:85%}}</style></head><body>
<h1>{html.escape(title)}</h1>
<p>Aircraft <b>{html.escape(str(fl.get('aircraft_id')))}</b>, flight
<b>{html.escape(str(fl.get('flight_id')))}</b>, epoch {html.escape(str(fl.get('epoch_utc')))};
software {html.escape(str((summary.get('software') or {}).get('version')))}.</p>
<h2>Inputs</h2><ul>{inputs}</ul>
<h2>Methods</h2>{_method_table(summary)}
{_fleet_section(summary)}
<h2>Warnings</h2><ul>{warn or '<li>none</li>'}</ul>
<h2>Figures</h2>{''.join(parts)}
</body></html>
"""
    target = folder / "report.html"
    with atomic_path(target) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return target
