"""ADS/ARMS inputs and settings: the noise model (:class:`ArmsModel`), the radar plots
(:class:`RadarPlots`) and the air-data velocity (:class:`AirData`) at their own times, and the
names of the radar linearisations (:data:`LINEARISATIONS`, :data:`CONVERTED_AT`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightrecon.errors import ValidationError

LINEARISATIONS = ("ekf", "converted")
"""Stage-1 / joint radar linearisations: EKF on (range, azimuth) or converted x/y measurements."""


CONVERTED_AT = ("predicted", "measured")
"""Where the converted-measurement covariance is evaluated (range and azimuth of the predicted
state, or the measured ones).  ``predicted`` avoids the correlation between the measurement noise
and its own covariance that ``measured`` introduces (Bar-Shalom, Li & Kirubarajan 2001,
sec. 10.4)."""


_LIN_CODE = {("ekf", "predicted"): 0, ("ekf", "measured"): 0,
             ("converted", "measured"): 1, ("converted", "predicted"): 2}


def linearisation_code(linearisation: str, converted_at: str) -> int:
    """The :class:`ArmsTrackModel`'s ``lin`` of a linearisation (:data:`LINEARISATIONS`) and
    converted-covariance point (:data:`CONVERTED_AT`): 0 EKF, 1 converted at the measured
    range/azimuth, 2 converted at the predicted ones.

    Raises
    ------
    ValidationError
        For a name not among those.
    """
    if linearisation not in LINEARISATIONS:
        raise ValidationError(f"unknown ARMS linearisation '{linearisation}'; choose from "
                              f"{', '.join(LINEARISATIONS)}")
    if converted_at not in CONVERTED_AT:
        raise ValidationError(f"unknown converted-covariance point '{converted_at}'; choose from "
                              f"{', '.join(CONVERTED_AT)}")
    return _LIN_CODE[(linearisation, converted_at)]


@dataclass(frozen=True)
class ArmsModel:
    """Noise model of the ADS/ARMS estimators (SI units).

    Attributes
    ----------
    sigma_range_m : standard deviation of the (horizontal) range error, sigma_rho (paper eq. 11)
    sigma_azimuth_rad : standard deviation of the azimuth error, sigma_theta, in radians
    q_m2ps3 : power spectral density of the CV model's acceleration noise [m^2/s^3]
    gm_sigma_mps : stationary standard deviation of each air-data error axis, sigma (paper eq. 4)
    gm_tau_s : its correlation time 1/alpha [s]
    sigma_air_mps : white noise on each air-data velocity component V* (0 allowed: paper)
    v0_sd_mps : prior standard deviation of each ground-velocity component at the first plot
    """

    sigma_range_m: float = 50.0
    sigma_azimuth_rad: float = float(np.deg2rad(0.25))
    q_m2ps3: float = 0.5
    gm_sigma_mps: float = 20.0
    gm_tau_s: float = 360.0
    sigma_air_mps: float = 0.5
    v0_sd_mps: float = 300.0

    def __post_init__(self) -> None:
        for name in ("sigma_range_m", "sigma_azimuth_rad", "q_m2ps3", "gm_sigma_mps",
                     "gm_tau_s", "v0_sd_mps"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValidationError(f"ARMS model: {name} must be positive and finite, got {v}")
        if not (np.isfinite(self.sigma_air_mps) and self.sigma_air_mps >= 0):
            raise ValidationError("ARMS model: sigma_air_mps must be >= 0 and finite, "
                                  f"got {self.sigma_air_mps}")

    @property
    def alpha_ps(self) -> float:
        """Inverse correlation time alpha = 1/tau [1/s]."""
        return 1.0 / self.gm_tau_s


@dataclass(frozen=True)
class RadarPlots:
    """Radar plots at their own times, one per row (station frame, SI).

    Attributes
    ----------
    t_s : (N,) plot times, strictly increasing [s]
    range_m : (N,) *horizontal* range r [m] (see :func:`horizontal_range`)
    azimuth_rad : (N,) azimuth, clockwise from true north [rad]
    sigma_range_m : (N,) standard deviation of ``range_m`` per plot [m]
    sigma_azimuth_rad : (N,) standard deviation of the azimuth per plot [rad]
    """

    t_s: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray
    sigma_range_m: np.ndarray
    sigma_azimuth_rad: np.ndarray

    @classmethod
    def from_arrays(cls, t_s, range_m, azimuth_rad, model: ArmsModel,
                    sigma_range_m=None) -> RadarPlots:
        """Build and validate plots; the sigmas default to the model's constants."""
        t = np.asarray(t_s, dtype=np.float64)
        r = np.asarray(range_m, dtype=np.float64)
        a = np.asarray(azimuth_rad, dtype=np.float64)
        if t.ndim != 1 or r.shape != t.shape or a.shape != t.shape:
            raise ValidationError("radar plots: t_s, range and azimuth must be 1-D of equal length")
        if len(t) < 2:
            raise ValidationError(f"radar plots: need at least 2 plots, got {len(t)}")
        bad = ~(np.isfinite(t) & np.isfinite(r) & np.isfinite(a))
        if bad.any():
            raise ValidationError("radar plots: non-finite time, range or azimuth",
                                  rows=np.flatnonzero(bad)[:20] + 1)
        if np.any(r <= 0):
            raise ValidationError("radar plots: range must be positive",
                                  rows=np.flatnonzero(r <= 0)[:20] + 1)
        if np.any(np.diff(t) <= 0):
            raise ValidationError("radar plots: times must be strictly increasing",
                                  rows=np.flatnonzero(np.diff(t) <= 0)[:20] + 2)
        sr = (np.full(t.shape, model.sigma_range_m) if sigma_range_m is None
              else np.asarray(sigma_range_m, dtype=np.float64))
        st = np.full(t.shape, model.sigma_azimuth_rad)
        return cls(t, r, a, sr, st)


@dataclass(frozen=True)
class AirData:
    """Air-data velocity V* = (TAS sin heading, TAS cos heading) at its own times (SI).

    Attributes
    ----------
    t_s : (M,) strictly increasing times [s]
    vx_mps, vy_mps : (M,) east and north components [m/s]
    """

    t_s: np.ndarray
    vx_mps: np.ndarray
    vy_mps: np.ndarray

    @classmethod
    def from_tas_heading(cls, t_s, tas_mps, heading_deg) -> AirData:
        """From true airspeed [m/s] and true heading [deg] (paper eq. 6: V* = V + dV)."""
        t = np.asarray(t_s, dtype=np.float64)
        v = np.asarray(tas_mps, dtype=np.float64)
        h = np.deg2rad(np.asarray(heading_deg, dtype=np.float64))
        return cls(t, v * np.sin(h), v * np.cos(h))

    def at(self, t_s: np.ndarray, max_gap_s: float = np.inf) -> np.ndarray:
        """(K, 2) components linearly interpolated to times ``t_s``.

        Air data is an *input* channel on the recorder grid (docs/schema.md, "Two kinds of
        channel"), so taking it at a plot's time by interpolation between neighbouring grid
        samples reuses no measurement.  NaN outside the samples and where the two bracketing
        samples are more than ``max_gap_s`` apart (a gap in the air data is not bridged).
        """
        t = np.asarray(t_s, dtype=np.float64)
        out = np.column_stack([np.interp(t, self.t_s, self.vx_mps, left=np.nan, right=np.nan),
                               np.interp(t, self.t_s, self.vy_mps, left=np.nan, right=np.nan)])
        if np.isfinite(max_gap_s) and len(self.t_s) > 1:
            j = np.clip(np.searchsorted(self.t_s, t), 1, len(self.t_s) - 1)
            gap = self.t_s[j] - self.t_s[j - 1]
            exact = (self.t_s[j] == t) | (self.t_s[j - 1] == t)
            out[(gap > max_gap_s) & ~exact] = np.nan
        return out
