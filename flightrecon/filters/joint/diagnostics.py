"""Diagnostics of a joint smoother run: per-source residual statistics, the estimated clock
offsets and sensor errors that deserve a word."""

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


def clock_warnings(run: JointRun) -> list[str]:
    """A warning per clock offset estimated beyond 3 sd and 0.05 s (it was corrected)."""
    return [f"joint: {name} clock offset {o:+.2f} s (sd {sd:.2f} s) estimated and corrected "
            f"(seconds added to the {name} times, as `clean --{name}-clock-offset` takes it)"
            for name, (o, sd) in run.clock_offsets_s.items()
            if np.isfinite(sd) and abs(o) > 3 * sd and abs(o) > 0.05]


IMPLAUSIBLE_PRIOR_SD = 8.0
"""A sensor error estimated this many prior sd from its prior mean makes the joint track
unhealthy (docs/output.md, "Method health"): under the prior such a value has a probability
below 1e-15, and where it happened the smoother had used the error to explain a model mismatch
(JSBSim cross-country without the gust state: an airspeed scale of +26 %; a spin whose loads
saturate: -82 %)."""


def implausible_corrections(corrections: dict[str, Any],
                            limit: float = IMPLAUSIBLE_PRIOR_SD) -> dict[str, float]:
    """The sensor errors (the summary's ``corrections``: value, prior_mean, prior_sd) estimated
    more than ``limit`` prior sd from their prior mean, with that distance."""
    out = {}
    for name, c in corrections.items():
        sd = c.get("prior_sd")
        if sd and np.isfinite(c["value"]):
            z = abs(c["value"] - c["prior_mean"]) / sd
            if z > limit:
                out[name] = float(z)
    return out


def far_warning(name: str, c: dict[str, Any], z: float) -> str:
    """The warning of an implausible sensor error ``name`` (``c``: its correction entry)."""
    return (f"joint: {name} estimated at {c['value']:+.4g} (sd {c['sd']:.2g}), {z:.0f} prior "
            f"sd from its prior {c['prior_mean']:+.4g} (sd {c['prior_sd']:.2g}): no sensor is "
            "that far off, the smoother explained something else with it (unhealthy)")


def gust_warnings(run: JointRun, upper_mps: float) -> list[str]:
    """A warning when the estimated gust sd ended at its upper bound ``upper_mps``: the air
    data then disagree with the rest by more than turbulence explains, and the smoother
    has all but stopped using them (JSBSim circuit 7009, departure only: 8 m/s, the pressure
    altitude and the air data both flagged inconsistent, the track unhealthy)."""
    g = run.gust or {}
    if g.get("rounds") and g.get("sd_mps", 0.0) >= upper_mps * (1.0 - 1e-9):
        return [f"joint: the turbulence's gust sd reached its upper bound {upper_mps:g} m/s: "
                "the air data disagree with the other sources by more than turbulence "
                "explains and carry little weight (check the airspeed and heading channels, "
                "their units, and the metadata)"]
    return []
