"""The recorded loads integrated through the recorded attitude against the GPS, per minute, on the
PH-LAB flight-test records (issue #35; docs/realflights.md, "Why the joint smoother fails on
these flights").

For each window of ``--window`` seconds (60) between lift-off and the record's end or touchdown:
the change of velocity that the joint smoother's own input gives, the cleaned loads rotated to
north-east-down through the recorded attitude and the propagated heading
(``joint_inputs(clean).acc_ned``) integrated over the window, minus the change of the GPS
velocity (a least-squares slope of the GPS positions over 30 s at each end), and the rms of the
load's departure from 1 g, ``| |f| - 1 |``, over the window.  Where the attitude reference
holds, the difference is the GPS's own noise (1-2 m/s here); where the attitude is tilted by
``delta``, it grows by ``g delta`` times the window.

The flight's folder is read with the tool (``flightrecon.ingest.load_flight``) through the
mapping and sidecar that ``scripts/realflight_study.py`` writes (recorder channels only); the
data are never copied.

Run::

    python scripts/attitude_load_check.py --data /path/to/matlab --flight b22 --start-at 2600
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

import realflight_study as rs  # noqa: E402


def _slope(t: np.ndarray, x: np.ndarray, half_s: float) -> np.ndarray:
    """Least-squares slope of ``x`` over a centred window of ``2 half_s`` (uniform ``t``)."""
    k = max(int(round(half_s / float(np.median(np.diff(t))))), 1)
    tt, xx = pd.Series(t), pd.Series(x)
    r = 2 * k + 1
    m_t, m_x = tt.rolling(r, center=True).mean(), xx.rolling(r, center=True).mean()
    m_tx, m_tt = (tt * xx).rolling(r, center=True).mean(), (tt * tt).rolling(r, center=True).mean()
    return ((m_tx - m_t * m_x) / (m_tt - m_t ** 2)).to_numpy()


def _cumulative(t: np.ndarray, a: np.ndarray) -> np.ndarray:
    out = np.zeros(len(t))
    aa = np.nan_to_num(a)
    out[1:] = np.cumsum(0.5 * (aa[1:] + aa[:-1]) * np.diff(t))
    return out


def windows(data: Path, flight: str, window_s: float, start_s: float | None = None
            ) -> pd.DataFrame:
    """One row per window (from ``start_s``, default 30 s after lift-off): start, end [s],
    INS minus GPS velocity change north, east and its magnitude [m/s], rms of the load's
    departure from 1 g [g] and of the kinematic acceleration's magnitude [g] (the two drivers
    of ``flightrecon/methods/joint/tilt.py``)."""
    from flightrecon.cleaning import CleaningSettings, clean_flight
    from flightrecon.ingest import load_flight
    from flightrecon.methods.joint.problem import joint_inputs

    folder = data if flight == "ref" else data / "Our-data"
    df, stems = rs.analyst_table(folder)
    facts = rs.flight_facts(df)
    with tempfile.TemporaryDirectory(prefix="attitude-check-") as tmp:
        sidecar = rs.write_case(facts, stems, Path(tmp), flight, arrival="none", gnss=False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            clean = clean_flight(load_flight(folder, sidecar=sidecar),
                                 settings=CleaningSettings(start=facts["lineup_s"]))
    inp = joint_inputs(clean)
    t = inp.t_in

    class _Rec:   # what truth_ne reads of a reconstruction
        pass

    rec = _Rec()
    rec.clean = clean  # type: ignore[attr-defined]
    tn, te = rs.truth_ne(rec, df, t)
    vn, ve = _slope(t, tn, 15.0), _slope(t, te, 15.0)
    In, Ie = _cumulative(t, inp.acc_ned[:, 0]), _cumulative(t, inp.acc_ned[:, 1])
    f = np.asarray(inp.f_body_g, float)
    dev = np.abs(np.linalg.norm(np.nan_to_num(f), axis=1) - 1.0)
    # the aircraft's own acceleration [g]: the specific force's departure from gravity alone,
    # in magnitude and direction (a coordinated turn: tan(roll); a zero-g parabola: 1)
    acc_g = np.linalg.norm(np.nan_to_num(inp.acc_ned), axis=1) / 9.80665
    ph = clean.phases
    t0 = ph.liftoff_t_s + 30.0 if start_s is None else max(start_s, ph.liftoff_t_s)
    t1 = (ph.touchdown_t_s if np.isfinite(ph.touchdown_t_s) else t[-1]) - 30.0
    rows = []
    for a in np.arange(t0, t1 - window_s, window_s):
        i, j = np.searchsorted(t, [a, a + window_s])
        if not np.isfinite([vn[i], vn[j], ve[i], ve[j]]).all():
            continue
        dn = (In[j] - In[i]) - (vn[j] - vn[i])
        de = (Ie[j] - Ie[i]) - (ve[j] - ve[i])
        rows.append({"start_s": float(t[i]), "end_s": float(t[j]), "dv_north_mps": dn,
                     "dv_east_mps": de, "dv_mps": float(np.hypot(dn, de)),
                     "load_departure_rms_g": float(np.sqrt(np.mean(dev[i:j] ** 2))),
                     "acceleration_rms_g": float(np.sqrt(np.mean(acc_g[i:j] ** 2)))})
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, required=True,
                    help="the fetched 'matlab' folder (flight 'ref'; 'Our-data' inside: B22)")
    ap.add_argument("--flight", choices=("ref", "b22"), default="b22")
    ap.add_argument("--window", type=float, default=60.0, help="window length [s]")
    ap.add_argument("--start-at", type=float, default=None,
                    help="start of the first window [s of the record] (default: lift-off + 30 s)")
    a = ap.parse_args(argv)
    w = windows(a.data, a.flight, a.window, a.start_at)
    print(w.to_string(index=False, float_format=lambda x: f"{x:.2f}"))
    for lo, hi in ((0.0, 0.05), (0.05, 0.3), (0.3, 10.0)):
        sel = (w["load_departure_rms_g"] >= lo) & (w["load_departure_rms_g"] < hi)
        if sel.any():
            print(f"load departure {lo:g}-{hi:g} g: {int(sel.sum())} windows, |dv| median "
                  f"{w['dv_mps'][sel].median():.1f} m/s, largest {w['dv_mps'][sel].max():.1f}")
    for col in ("load_departure_rms_g", "acceleration_rms_g"):
        rho = w["dv_mps"].corr(w[col], method="spearman")
        print(f"rank correlation of |dv| with {col}: {rho:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
