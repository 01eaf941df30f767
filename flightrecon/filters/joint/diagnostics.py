"""Diagnostics of a joint smoother run: per-source residual statistics."""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.filters.joint.settings import SOURCES
from flightrecon.filters.joint.smoother import JointRun


def source_report(run: JointRun, flag_fraction: float = 0.01) -> dict[str, Any]:
    """Per source: measurements used, mean squared normalised residual, down-weighted ones
    and their time spans; a source with more than ``flag_fraction`` of its residuals beyond
    5 sigma is flagged inconsistent."""
    out: dict[str, Any] = {}
    m = run.meas
    for s_i, name in enumerate(SOURCES):
        sel = m.source == s_i
        if not sel.any():
            continue
        rn = run.resid_norm[sel]
        w = run.weights[sel]
        t = m.t[sel]
        down = w < 0.999
        big = np.abs(rn) > 5.0
        spans = []
        if big.any():
            tb = np.unique(t[big])
            start = prev = tb[0]
            for ti in tb[1:]:
                if ti - prev > 10.0:
                    spans.append([float(start), float(prev)])
                    start = ti
                prev = ti
            spans.append([float(start), float(prev)])
        innov_ok = np.isfinite(run.innov[sel]) & (run.innov_var[sel] > 0)
        nis = run.innov[sel][innov_ok] ** 2 / run.innov_var[sel][innov_ok]
        out[name] = {"count": int(sel.sum()),
                     "mean_norm_residual_sq": float(np.nanmean(rn ** 2)),
                     "mean_nis": float(np.mean(nis)) if len(nis) else None,
                     "downweighted": int(down.sum()),
                     "beyond_5_sigma": int(big.sum()),
                     "flagged_inconsistent": bool(big.mean() > flag_fraction),
                     "flagged_spans_s": spans[:50]}
    return out
