"""Polarity of the load factors and of the bank against the turn, checked on the merged flight
table (docs/schema.md, "Conventions"; docs/ingest.md, "Validation").

``n_norm_g`` is +1 at rest and about +1 on average in flight, so a median near -1 means a
flipped channel; at rest ``n_long_g = sin(pitch)`` (the specific force is g0 up; its forward
body component is g0 sin(theta)), so ``n_long_g`` matching ``-sin(pitch)`` means a flipped
channel; a right bank turns the heading clockwise.  A flipped channel is refused, naming the
fix (``sign = -1`` in a mapping file).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.constants import G0
from flightrecon.errors import ValidationError
from flightrecon.ingest.validate import Provenance


#: true airspeed below which a sample counts as "at rest / taxiing" for the polarity checks;
#: below every transport or light aircraft's stall speed (about 25 m/s = 49 kt)
GROUND_TAS_MPS = 20.0
#: minimum number of samples for a polarity verdict (a median of fewer is not trusted)
MIN_POLARITY_SAMPLES = 16


class _Sampled:
    """Each channel's samples, extracted once for all the polarity checks: ``sampled(name)``
    is ``(values, mask of sampled rows, values there, their times)``."""

    def __init__(self, data: pd.DataFrame):
        self.data = data
        self.t = data["t_s"].to_numpy()
        self._cache: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}

    def __call__(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        if name not in self._cache:
            v = self.data[name].to_numpy()
            ok = ~np.isnan(v)
            self._cache[name] = (v, ok, v[ok], self.t[ok])
        return self._cache[name]


def _on_common_rows(sampled: _Sampled, a: str, b: str) -> tuple[np.ndarray, np.ndarray]:
    """Values of ``b`` interpolated (linearly in time) at the rows where ``a`` was sampled."""
    _, ia, va, ta = sampled(a)
    vb_all, ib, vb, tb = sampled(b)
    if len(vb) < 2:
        return va, np.full(len(va), np.nan)
    if ib[ia].all():                      # sampled on the same rows: no interpolation needed
        return va, vb_all[ia]
    return va, np.interp(ta, tb, vb, left=np.nan, right=np.nan)


def check_polarity(data: pd.DataFrame, prov: Provenance) -> list[str]:
    """Polarity checks of the load factors (see the module docstring).

    Raises
    ------
    ValidationError
        ``n_norm_g`` or ``n_long_g`` flipped.
    """
    warns: list[str] = []
    sampled = _Sampled(data)
    nn_ok = sampled("n_norm_g")[2]
    col = prov.source_column[0].get("n_norm_g", "n_norm_g")
    if nn_ok.size >= MIN_POLARITY_SAMPLES:
        med = float(np.median(nn_ok))
        if med < 0.0:
            raise ValidationError(f"n_norm_g looks flipped: median {med:.2f} g over the record; "
                                  "it is +1 at rest and about +1 in flight (n_norm = -f_z/g0). "
                                  "Use sign = -1 in a mapping file", file=prov.files[0],
                                  column=col)
    nn_r, tas_r = _on_common_rows(sampled, "n_norm_g", "tas_mps")
    ground = tas_r < GROUND_TAS_MPS
    if ground.sum() >= MIN_POLARITY_SAMPLES:
        med = float(np.median(nn_r[ground]))
        if abs(med - 1.0) > 0.3:
            raise ValidationError(f"n_norm_g is {med:.2f} g at rest (true airspeed below "
                                  f"{GROUND_TAS_MPS:g} m/s); expected +1 (n_norm = -f_z/g0): a "
                                  "flipped or mis-scaled channel", file=prov.files[0], column=col)
    _check_long_polarity(sampled, prov)
    _check_turn_polarity(sampled, prov)
    return warns


#: half-width of the window for the airspeed derivative in the n_long check [s]: long enough
#: to average airspeed noise (0.5 m/s noise -> 0.007 g), short against speed changes
ACCEL_HALF_WINDOW_S = 5.0


def _check_long_polarity(sampled: _Sampled, prov: Provenance) -> None:
    """``n_long_g`` sign: along the body x axis the specific force is the acceleration plus the
    component of g0 up, so n_long = dV/dt / g0 + sin(pitch) (exact at rest; in flight up to
    angle-of-attack and turn terms, small for a sign test).  A channel matching
    ``-(dV/dt / g0 + sin(pitch))`` twice as well as ``+(...)``, where that expected value is
    visibly non-zero (median above 0.02 g), is flipped.  dV/dt is the airspeed difference over
    +-5 s."""
    nl, pitch = _on_common_rows(sampled, "n_long_g", "pitch_deg")
    t = sampled("n_long_g")[3]
    _, _, vv, tt = sampled("tas_mps")
    if len(vv) < 2:
        return
    h = ACCEL_HALF_WINDOW_S
    # np.clip without its overhead (the times are finite)
    lo = np.minimum(np.maximum(t - h, tt[0]), tt[-1])
    hi = np.minimum(np.maximum(t + h, tt[0]), tt[-1])
    span = hi - lo
    with np.errstate(invalid="ignore", divide="ignore"):
        vdot = np.where(span > 0, (np.interp(hi, tt, vv) - np.interp(lo, tt, vv)) / span, np.nan)
    expected = np.sin(np.radians(pitch)) + vdot / G0
    ok = ~np.isnan(expected) & ~np.isnan(nl)
    if ok.sum() < MIN_POLARITY_SAMPLES:
        return
    e, n = expected[ok], nl[ok]
    if np.median(np.abs(e)) <= 0.02:
        return
    r_same = float(np.median(np.abs(n - e)))
    r_flip = float(np.median(np.abs(n + e)))
    if r_flip < 0.5 * r_same:
        raise ValidationError(
            f"n_long_g looks flipped: it matches -(sin(pitch) + dV/dt/g0) (median misfit "
            f"{r_flip:.3f} g) rather than +(sin(pitch) + dV/dt/g0) ({r_same:.3f} g); n_long_g "
            "is positive forward. Use sign = -1 in a mapping file", file=prov.files[0],
            column=prov.source_column[0].get("n_long_g", "n_long_g"))


#: thresholds for the turn check: bank and turn rate clearly non-zero, airborne speed
TURN_MIN_ROLL_DEG = 10.0
TURN_MIN_RATE_DEG_S = 0.5
TURN_MIN_TAS_MPS = 30.0
#: fraction of turning samples whose heading rate has the sign opposite to the bank
TURN_FLIP_FRACTION = 0.8


def _check_turn_polarity(sampled: _Sampled, prov: Provenance) -> None:
    """Bank and turn direction agree: in a coordinated turn the heading rate is
    ``g0 tan(roll) / V`` (docs/schema.md, "Conventions": roll + right wing down, heading
    clockwise), so
    a right bank turns the heading clockwise.  If at least 32 clearly turning samples mostly
    (> 80 %) turn against the bank, roll or heading has the wrong sign."""
    if "heading_deg" not in sampled.data.columns:
        return
    _, _, hdg, th = sampled("heading_deg")
    if len(hdg) < 3:
        return
    psi = np.unwrap(np.radians(hdg))
    dt = np.diff(th)
    rate = np.full(th.size, np.nan)
    ok = dt > 0
    mid = np.diff(psi)[ok] / dt[ok]
    # centred difference on the interior samples
    r = np.full(dt.size, np.nan)
    r[ok] = mid
    rate[1:-1] = 0.5 * (r[:-1] + r[1:])
    _, roll = _on_common_rows(sampled, "heading_deg", "roll_deg")
    _, tas = _on_common_rows(sampled, "heading_deg", "tas_mps")
    turning = (np.abs(roll) > TURN_MIN_ROLL_DEG) & (tas > TURN_MIN_TAS_MPS) \
        & (np.abs(rate) > np.radians(TURN_MIN_RATE_DEG_S))
    n = int(turning.sum())
    if n < 2 * MIN_POLARITY_SAMPLES:
        return
    against = np.sign(rate[turning]) != np.sign(roll[turning])
    frac = float(against.mean())
    if frac > TURN_FLIP_FRACTION:
        raise ValidationError(
            f"roll_deg or heading_deg has the wrong sign: in {100 * frac:.0f} % of {n} turning "
            "samples the heading turns against the bank (roll is + right wing down, heading "
            "clockwise from north, so a right bank turns the heading clockwise). Use sign = -1 in "
            "a mapping file", file=prov.files[0],
            column=prov.source_column[0].get("roll_deg", "roll_deg"))
