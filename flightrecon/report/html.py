"""A self-contained HTML report: figures embedded as data URIs, no external resource.

The page opens with a paragraph saying which method the result comes from and why and what
its warnings mean; then the flight, the events table (UTC), the figures, the methods compared
in a table, the sensor corrections, the warnings and the inputs with their SHA-256.
"""

from __future__ import annotations

import base64
import html
import io
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from flightrecon.events import utc_text
from flightrecon.export.atomic import atomic_path
from flightrecon.report.plots import (
    FIGURES,
    METHOD_NAMES,
    ReportContext,
    correction_rows,
    make_figures_ctx,
)

STATUS_MEANING = {
    "ok": "ran, converged, and its track is physically possible: it may feed the default result",
    "unhealthy": "ran, but failed a health check (no convergence, a non-finite position, a "
                 "lost covariance, or a track outside the physical envelope of the flight): kept "
                 "in the file for comparison, never used for the default result",
    "doubtful": "ran and its track is physically possible, but it leans on a channel whose "
                "unit the door's evidence doubts, or that was used against a certain "
                "contradiction the mapping confirmed (reason and figures given)",
    "failed": "stopped with an error (reason given): no track",
    "skipped": "not run: the data do not allow it (reason given) or it was not asked for",
}

#: what a warning means, by the text it starts with or contains
WARNING_MEANING = (
    ("wind unmodelled", "no wind channel was recorded, so this method takes the air-derived "
                        "velocity as ground velocity; the wind drift is absorbed by its "
                        "coefficients and its track is less reliable between the end points"),
    ("not converge", "an estimator did not converge: its numbers are not a solution and it is "
                     "excluded from the default result"),
    ("gap", "data are missing over a span; the uncertainty bands widen there"),
    ("spike", "isolated outliers were found and removed by the cleaning"),
    ("plausib", "a physical plausibility check failed over a span: check the channel named"),
    ("clock", "the time bases of two sources disagree; an offset was estimated or applied"),
)


def _e(x: Any) -> str:
    return html.escape(str(x))


def _num(x: Any, digits: int = 4) -> str:
    if x is None:
        return "–"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, (float, np.floating)):
        if not math.isfinite(x):
            return "–"
        return f"{x:.{digits}g}"
    return str(x)


def _png_bytes(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    return buf.getvalue()


def _share(track: pd.DataFrame) -> dict[str, float]:
    if "source" not in track.columns or len(track) == 0:
        return {}
    s = track["source"].astype("string").fillna("none")
    return (s.value_counts(normalize=True) * 100.0).to_dict()


def opening_paragraph(track: pd.DataFrame, summary: Mapping[str, Any]) -> str:
    """Which method the result comes from, why, and what the warnings mean (HTML)."""
    methods = summary.get("methods") or {}
    share = _share(track)
    joint = methods.get("joint") if isinstance(methods.get("joint"), Mapping) else None
    parts = []
    if not methods:
        return ("<p>This result carries no summary (a bare CSV file): which method produced "
                "it, its status and its warnings are unknown. Reconstruct again or keep the "
                "<code>.summary.json</code> beside the result.</p>")
    main = max(share, key=share.get) if share else None
    if joint is not None and joint.get("status") in ("ok", "stopped") and main == "joint":
        parts.append("The reconstructed track comes from the <b>joint smoother</b>, which "
                     "fuses every source (loads and attitude, air data, pressure altitude"
                     + (", GNSS" if (summary.get("measurements") or {}).get("gnss_fixes")
                        else "")
                     + (", radar" if (summary.get("measurements") or {}).get("radar_plots")
                        else "")
                     + ", end points, runway) with the sensor errors, wind and clock offsets "
                       "in its state. It is the default result because it ran, converged and "
                       "passed the health checks.")
    else:
        if joint is None:
            why = "did not run"
        else:
            probs = [str(p.get("what")) for p in (joint.get("health") or {}).get("problems", [])
                     if isinstance(p, Mapping)]
            because = "; ".join(x for x in [str(joint.get("reason") or "")] + probs if x)
            why = f"is {_e(joint.get('status'))}" + (f" ({_e(because)})" if because else "")
        parts.append(f"The joint smoother, the usual default, {why}; the track is therefore "
                     "taken sample by sample from the first <i>healthy</i> method of the "
                     "priority joint, SNS, ADS/ARMS, Sabziev, azimuth that covers the sample.")
        res = summary.get("result") if isinstance(summary.get("result"), Mapping) else {}
        if res.get("why"):
            parts.append(f"In the summary's words: {_e(res['why'])}.")
    if share:
        parts.append("Share of the samples by source: " + ", ".join(
            f"{_e(METHOD_NAMES.get(k, k))} {v:.1f} %" for k, v in
            sorted(share.items(), key=lambda kv: -kv[1])) + ".")
    bad = [m for m, st in methods.items() if isinstance(st, Mapping)
           and st.get("status") in ("unhealthy", "failed")]
    if bad:
        parts.append("Not used for the result: " + ", ".join(
            f"{_e(METHOD_NAMES.get(m, m))} ({_e(methods[m].get('status'))})" for m in bad)
            + " – see the methods table.")
    warns = summary.get("warnings") or []
    if warns:
        count = "is one warning" if len(warns) == 1 else f"are {len(warns)} warnings"
        parts.append(f"There {count}"
                     " (listed at the end with their meaning). Warnings do not invalidate the "
                     "result: they say where a source or a method is weaker, and the "
                     "uncertainty bands already include what the estimators could quantify.")
    else:
        parts.append("There are no warnings.")
    ev = summary.get("events") or []
    n_exc = sum(1 for e in ev if isinstance(e, Mapping) and e.get("kind") == "exceedance")
    if ev:
        parts.append(f"{len(ev)} events are listed below"
                     + (f", {n_exc} of them envelope exceedances" if n_exc else "")
                     + "; their numbers mark the map and every time plot.")
    return "<p class=lead>" + " ".join(parts) + "</p>"


def _warning_meaning(w: str) -> str:
    low = w.lower()
    for key, meaning in WARNING_MEANING:
        if key in low:
            return meaning
    return "see the message; the methods table tells which estimator it concerns"


def _short_utc(text: str | None) -> str | None:
    """``2026-01-01T10:00:23.000Z`` -> ``2026-01-01 10:00:23.0``."""
    if not text:
        return None
    return text.replace("T", " ").rstrip("Z")[:-2]


def events_html(summary: Mapping[str, Any]) -> str:
    rows = [e for e in summary.get("events") or [] if isinstance(e, Mapping)]
    if not rows:
        return "<p>No events recorded (a result without its summary has none).</p>"
    epoch = (summary.get("flight") or {}).get("epoch_utc")
    out = ["<table class=events><thead><tr><th>#</th><th>UTC</th><th>t [s]</th><th>until "
           "(UTC)</th><th>duration [s]</th><th>event</th><th>detail</th></tr></thead><tbody>"]
    for i, e in enumerate(rows, start=1):
        t, t1 = e.get("t_s"), e.get("end_t_s")
        utc = _short_utc(e.get("utc") or utc_text(epoch, t)) or "–"
        end = _short_utc(e.get("end_utc") or utc_text(epoch, t1)) or ""
        dur = "" if t1 is None or t is None else f"{float(t1) - float(t):.1f}"
        sev = _e(e.get("severity") or "info")
        out.append(f"<tr class={sev}><td>{i}</td><td>{_e(utc)}</td><td>{_num(t, 6)}</td>"
                   f"<td>{_e(end)}</td><td>{dur}</td><td>{_e(e.get('label'))}</td>"
                   f"<td>{_e(e.get('detail'))}</td></tr>")
    out.append("</tbody></table>")
    return "".join(out)


def _key_figures(name: str, st: Mapping[str, Any]) -> str:
    if name == "sabziev":
        bits = [f"mode {_e(st.get('mode'))}"]
        ks = [st.get(f"k{i}") for i in (1, 2, 3)]
        bits.append("k1, k2, k3 = " + ", ".join(_num(k) for k in ks))
        ax = st.get("axes") or {}
        if isinstance(ax, Mapping) and ax:
            bits.append("end-point residual " + ", ".join(
                f"{_e(a)} {_num((v or {}).get('residual_m'), 3)} m" for a, v in ax.items()
                if isinstance(v, Mapping)))
            bits.append("iterations " + ", ".join(
                f"{_e(a)} {_num((v or {}).get('iterations'))}" for a, v in ax.items()
                if isinstance(v, Mapping)))
        return "; ".join(bits)
    if name == "joint":
        bits = []
        it = st.get("iterations")
        if isinstance(it, list):
            bits.append(f"{len(it)} outer iterations")
        srcs = st.get("sources")
        if isinstance(srcs, Mapping):
            bits.append("sources: " + ", ".join(
                f"{_e(s)} ({_num((v or {}).get('count'))}, NIS {_num((v or {}).get('mean_nis'), 2)}"
                + (", flagged" if (v or {}).get("flagged_inconsistent") else "") + ")"
                for s, v in srcs.items() if isinstance(v, Mapping)))
        return "; ".join(bits)
    bits = []
    for k, v in st.items():
        if k in ("status", "reason", "health", "converged", "healthy", "corrections",
                 "history", "notes", "settings"):
            continue
        if isinstance(v, (bool, int, float, str)) and not isinstance(v, str) or (
                isinstance(v, str) and len(v) < 40):
            bits.append(f"{_e(k.replace('_', ' '))} {_e(_num(v))}")
    return "; ".join(bits[:10])


def methods_html(track: pd.DataFrame, summary: Mapping[str, Any]) -> str:
    methods = summary.get("methods") or {}
    if not methods:
        return "<p>No method information (no summary).</p>"
    share = _share(track)
    out = ["<table class=methods><thead><tr><th>method</th><th>status</th><th>converged</th>"
           "<th>share of the result</th><th>reason / health</th><th>key figures</th></tr>"
           "</thead><tbody>"]
    for name, st in methods.items():
        if not isinstance(st, Mapping):
            continue
        status = str(st.get("status"))
        health = st.get("health") if isinstance(st.get("health"), Mapping) else {}
        probs = "; ".join(_e(p.get("what")) for p in health.get("problems") or []
                          if isinstance(p, Mapping))
        notes = "; ".join(_e(n) for n in st.get("notes") or [])
        reason = "; ".join(x for x in (_e(st.get("reason") or ""), probs, notes) if x)
        out.append(f"<tr class=st-{_e(status)}><th>{_e(METHOD_NAMES.get(name, name))}"
                   f"<br><code>{_e(name)}</code></th><td>{_e(status)}</td>"
                   f"<td>{_num(st.get('converged'))}</td>"
                   f"<td>{share.get(name, 0.0):.1f} %</td><td>{reason or '–'}</td>"
                   f"<td>{_key_figures(name, st) if status not in ('skipped', 'failed') else ''}"
                   "</td></tr>")
    out.append("</tbody></table><p class=small>Status words: " + "; ".join(
        f"<b>{k}</b>: {v}" for k, v in STATUS_MEANING.items()) + ".</p>")
    return "".join(out)


def corrections_html(summary: Mapping[str, Any], sensor_truth: Mapping[str, Any] | None) -> str:
    rows = correction_rows(summary, sensor_truth)
    if not rows:
        return "<p>No sensor corrections estimated.</p>"
    out = ["<table class=corr><thead><tr><th>method</th><th>correction</th><th>unit</th>"
           "<th>estimate</th><th>2 sigma</th><th>truth</th><th>definition</th></tr></thead>"
           "<tbody>"]
    for r in rows:
        out.append(f"<tr><td>{_e(METHOD_NAMES.get(r['method'], r['method']))}</td>"
                   f"<td>{_e(r['name'])}</td><td>{_e(r['unit'])}</td>"
                   f"<td>{_num(r['value'], 3)}</td><td>{_num(r['two_sigma'], 2)}</td>"
                   f"<td>{_num(r['truth'], 3)}</td><td class=small>{_e(r['note'])}</td></tr>")
    out.append("</tbody></table>")
    return "".join(out)


def _flight_html(track: pd.DataFrame, summary: Mapping[str, Any]) -> str:
    fl = summary.get("flight") or {}
    epoch = fl.get("epoch_utc")
    t = track["t_s"].to_numpy(float) if "t_s" in track.columns and len(track) else np.array([])
    rows = [("aircraft", fl.get("aircraft_id")), ("flight", fl.get("flight_id")),
            ("record", f"{_short_utc(utc_text(epoch, t[0])) or _num(t[0])} to "
                       f"{_short_utc(utc_text(epoch, t[-1])) or _num(t[-1])} UTC "
                       f"({t[-1] - t[0]:.0f} s)"
             if len(t) else "–")]
    for key in ("departure", "arrival", "station"):
        p = fl.get(key)
        if isinstance(p, Mapping) and p.get("lat_deg") is not None:
            txt = (f"{p['lat_deg']:.5f}°, {p['lon_deg']:.5f}°, {float(p.get('elev_m') or 0):.0f} m "
                   "MSL")
            if p.get("runway_true_deg") is not None:
                txt += f"; runway {float(p['runway_true_deg']):.0f}° true"
            rows.append((key, txt))
    if fl.get("geoid_undulation_m") is not None:
        rows.append(("geoid undulation", f"{float(fl['geoid_undulation_m']):g} m (ellipsoid "
                     "minus MSL; altitudes MSL = ellipsoidal height minus this)"))
    meas = summary.get("measurements") or {}
    if meas:
        rows.append(("measurements", f"{meas.get('gnss_fixes', 0)} GNSS fixes, "
                     f"{meas.get('radar_plots', 0)} radar plots"))
    sw = summary.get("software") or {}
    if sw:
        rows.append(("software", f"flightrecon {sw.get('version')} (Python {sw.get('python')})"))
    return "<table class=kv>" + "".join(f"<tr><th>{_e(k)}</th><td>{_e(v if v is not None else '–')}"
                                        "</td></tr>" for k, v in rows) + "</table>"


_CSS = """body{font-family:system-ui,sans-serif;max-width:1150px;margin:auto;padding:1em;
color:#111;line-height:1.35}
img{max-width:100%;border:1px solid #ddd}
table{border-collapse:collapse;margin:.5em 0;font-size:90%}
td,th{border:1px solid #ccc;
padding:3px 6px;text-align:left;vertical-align:top}
thead th{background:#eee}
tr.alert td{background:#fde8e8}
tr.caution td{background:#fff6dd}
tr.st-fallback td,
tr.st-stopped td{background:#fff6dd}
tr.st-unhealthy td,
tr.st-failed td{background:#fde8e8}
tr.st-skipped td{color:#777}
.lead{font-size:105%;
background:#f3f6fb;padding:.7em;border-left:4px solid #3a6ea5}
.small{font-size:85%;color:#444}
figure{margin:1.2em 0}
table.events td:nth-child(2),table.events td:nth-child(4){white-space:nowrap}
figcaption{font-size:90%;color:#333}
code{font-size:85%}
"""

_SCRIPT = """<script>
window.addEventListener('load', function () {
  var imgs = document.querySelectorAll('figure img');
  var ok = 0;
  imgs.forEach(function (i) { if (i.complete && i.naturalWidth > 0) { ok += 1; } });
  document.body.setAttribute('data-figures', String(imgs.length));
  document.body.setAttribute('data-figures-loaded', String(ok));
});
</script>"""


def _fleet_section(summary: Mapping[str, Any]) -> str:
    """Which fleet calibration and coefficients the reconstruction used (``--use-fleet-
    coefficients``), from how many flights; empty when none was used."""
    fc = summary.get("fleet_coefficients")
    if not fc:
        return ""
    cal = fc.get("calibration")
    out = ['<h2 id="fleet">Fleet calibration</h2>']
    if cal:
        rows = "".join(
            f"<tr><td>{_e(n)}</td><td>{q['mean']:.4g}</td><td>{q['sd']:.3g}</td><td>{q['n']}</td>"
            f"<td>{'yes' if q['applied'] else 'no'}</td></tr>"
            for n, q in cal["errors"].items())
        out.append(f"<p>Sensor calibration of aircraft <b>{_e(str(fc['aircraft_id']))}</b> at "
                   f"{_e(str(cal['at_utc']))} from <b>{cal['n_flights']}</b> flight(s) "
                   f"({_e(', '.join(cal['flights']))}) of store <code>{_e(str(fc['store']))}"
                   "</code>; the errors marked applied were the joint smoother's priors.</p>"
                   "<table><tr><th>error</th><th>mean</th><th>sd</th><th>flights</th>"
                   f"<th>applied</th></tr>{rows}</table>")
    else:
        out.append(f"<p>No sensor calibration: {_e(str(fc.get('calibration_missing')))}</p>")
    if fc.get("k") is not None:
        out.append(f"<p>Sabziev fleet-mean k = {_e(str(fc['k']))} (fits per axis "
                   f"{_e(str(fc['flights']))}).</p>")
    return "".join(out)


def write_report(folder: str | Path, track: pd.DataFrame, summary: Mapping[str, Any],
                 truth: pd.DataFrame | None = None, title: str = "flightrecon report", *,
                 grid: pd.DataFrame | None = None, gnss: pd.DataFrame | None = None,
                 sensor_truth: Mapping[str, Any] | None = None,
                 notes: list[str] | None = None, radar: pd.DataFrame | None = None) -> Path:
    """Write ``report.html`` and one PNG per figure into ``folder`` (created if needed).

    Parameters
    ----------
    track, summary : the result table and its summary
    truth : truth table of a simulated flight (drawn for comparison)
    grid : the recorder's channels (attitude, load factors, airspeed, pressure altitude);
        without it those figures are left out and the page says so
    gnss : GNSS fixes (``t_s``, ``lat_deg``, ``lon_deg``) drawn on the map
    radar : radar plots (range, azimuth, elevation from the station) drawn on the map
    sensor_truth : the simulated sensor errors, overlaid on the corrections
    notes : sentences added under the opening paragraph

    Returns the path of the HTML page.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    ctx = ReportContext(track, summary, truth, grid, gnss, sensor_truth, radar)
    figs = make_figures_ctx(ctx)
    parts = []
    for name, fig in figs.items():
        png = _png_bytes(fig)
        with atomic_path(folder / f"{name}.png") as tmp:
            tmp.write_bytes(png)
        uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
        caption = FIGURES[name][1]
        parts.append(f'<figure id="fig-{name}" data-figure="{name}"><img alt="{_e(caption)}" '
                     f'src="{uri}"><figcaption>{_e(caption)}</figcaption></figure>')
    notes = list(notes or [])
    if grid is None and not notes:
        notes.append("The recorder log was not available to the report: attitude, load "
                     "factors, airspeed and pressure altitude are not drawn.")
    warn = "".join(f"<tr><td>{_e(w)}</td><td>{_e(_warning_meaning(str(w)))}</td></tr>"
                   for w in summary.get("warnings") or [])
    inputs = "".join(f"<li><code>{_e(i.get('path'))}</code> sha256 <code>{_e(i.get('sha256'))}"
                     "</code></li>" for i in summary.get("inputs") or [] if isinstance(i, Mapping))
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{_e(title)}</title>
<style>{_CSS}</style></head><body>
<h1>{_e(title)}</h1>
{opening_paragraph(track, summary)}
{''.join(f'<p class=small>{_e(n)}</p>' for n in notes)}
<h2 id="flight">Flight</h2>{_flight_html(track, summary)}
<h2 id="events">Events</h2>{events_html(summary)}
<h2 id="figures">Figures</h2>{''.join(parts)}
<h2 id="methods">Methods compared</h2>{methods_html(track, summary)}
<h2 id="corrections">Sensor corrections</h2>{corrections_html(summary, sensor_truth)}
{_fleet_section(summary)}
<h2 id="warnings">Warnings</h2>
{'<table><thead><tr><th>warning</th><th>what it means</th></tr></thead><tbody>' + warn
 + '</tbody></table>' if warn else '<p>none</p>'}
<h2 id="inputs">Inputs</h2><ul>{inputs or '<li>unknown (no summary)</li>'}</ul>
{_SCRIPT}
</body></html>
"""
    target = folder / "report.html"
    with atomic_path(target) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return target
