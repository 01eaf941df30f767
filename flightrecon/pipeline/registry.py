"""The method registry: which estimators exist, their settings (:class:`ReconstructSettings`),
when each can run on a flight and how it is called."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import pandas as pd

from flightrecon.errors import MetadataError
from flightrecon.types import CleanFlight, MethodResult

#: method name -> (module, function)
METHOD_FUNCTIONS: dict[str, tuple[str, str]] = {
    "joint": ("flightrecon.filters.joint_method", "run_joint"),
    "sabziev": ("flightrecon.fusion.method", "run_sabziev"),
    "arms": ("flightrecon.filters.arms_method", "run_arms"),
    "azimuth": ("flightrecon.filters.azimuth_method", "run_azimuth"),
    "sns": ("flightrecon.filters.sns_method", "run_sns"),
}


ALL_METHODS: tuple[str, ...] = tuple(METHOD_FUNCTIONS)


#: order in which methods supply the unprefixed horizontal track, sample by sample
DEFAULT_PRIORITY: tuple[str, ...] = ("joint", "sns", "arms", "sabziev", "azimuth")


@dataclass(frozen=True)
class ReconstructSettings:
    """Settings of one reconstruction (written into the summary so the run can be repeated).

    Attributes
    ----------
    methods : methods to run; ``None`` runs every method the flight's data allows
    rate_hz : grid rate for the input channels (``None``: the fastest input channel's rate)
    k : Sabziev coefficients (k1, k2, k3) for the initial-value mode (no arrival point needed)
    k_sd : their standard deviations (fleet spread), propagated into the Sabziev track
    arms_form, arms_linearisation : ADS/ARMS estimator form (``joint``/``cascade``) and
        linearisation (``ekf``/``converted``)
    azimuth_model : ``aided`` or ``singer``
    sns_model, sns_form : SNS dead-reckoning model (``auto``/``airspeed``/``doppler``) and
        filter form (``consistent``/``seed``)
    joint_noise : overrides of the joint smoother's error budget
        (:class:`flightrecon.filters.joint.JointNoise` field -> value)
    joint_estimate_noise : scale each source's noise from the flight's own residuals
    joint_priors : ``(error, mean, sd)`` priors of the joint smoother's sensor-error states
        (names of :data:`flightrecon.filters.joint.PRIOR_STATES`), e.g. an aircraft's fleet
        calibration (:func:`flightrecon.store.fleet.fleet_settings`)
    strict : raise on the first method that fails, does not converge or is unhealthy
    keep_unhealthy : when no method is healthy, return (and let the CLI write) the unhealthy
        tracks under their prefixes for inspection instead of raising
        :class:`~flightrecon.errors.NoResultError`
    sns_noise : overrides of the SNS noise (:func:`flightrecon.filters.sns_method.sns_noise_with`)
    start, end : trim the record to ``start <= t_s <= end`` before cleaning (seconds from the
        epoch or UTC timestamps; :func:`flightrecon.cleaning.trim.trim_flight`)
    """

    methods: tuple[str, ...] | None = None
    rate_hz: float | None = None
    k: tuple[float, float, float] | None = None
    k_sd: tuple[float, float, float] | None = None
    arms_form: str = "joint"
    arms_linearisation: str = "ekf"
    azimuth_model: str = "aided"
    sns_model: str = "auto"
    sns_form: str = "consistent"
    joint_noise: dict[str, float] | None = None
    joint_estimate_noise: bool = False
    joint_priors: tuple[tuple[str, float, float], ...] | None = None
    strict: bool = False
    keep_unhealthy: bool = False
    start: float | str | None = None
    end: float | str | None = None
    sns_noise: dict[str, float] | None = None


@dataclass(frozen=True)
class Reconstruction:
    """Result of :func:`reconstruct`: the combined track, the summary and the pieces."""

    track: pd.DataFrame
    summary: dict[str, Any]
    clean: CleanFlight
    results: dict[str, MethodResult] = field(default_factory=dict)


def available_methods(clean: CleanFlight, settings: ReconstructSettings) -> dict[str, str | None]:
    """Which methods the data allow: name -> ``None`` if runnable, else the reason it is not."""
    meta = clean.meta
    out: dict[str, str | None] = {}
    g = clean.grid
    needed = [c for c in ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg",
                          "heading_deg", "tas_mps") if c not in g.columns]
    out["joint"] = None if not needed else f"missing input channels {', '.join(needed)}"
    from flightrecon.fusion.method import end_fix

    has_end = meta.arrival is not None or settings.k is not None or end_fix(clean) is not None
    out["sabziev"] = None if has_end else (
        "no arrival point and no coefficients (give --arrival, a --fix at the end of the "
        "record, or --k / fleet coefficients)")
    has_radar = len(clean.radar) > 0 and "arms_azimuth_deg" in clean.radar.columns
    if not has_radar:
        reason = "no radar plots in the data"
    elif meta.station is None:
        reason = "radar plots but no station position (give --station)"
    else:
        reason = None
    out["arms"] = reason
    out["azimuth"] = reason
    has_gnss = len(clean.gnss) > 0 and "gnss_lat_deg" in clean.gnss.columns
    out["sns"] = None if has_gnss else "no GNSS fixes in the data"
    if meta.departure is None:
        out["sabziev"] = out["sabziev"] or ("no departure airfield (the fusion integrates from "
                                            "the lift-off point; give --departure)")
        if meta.origin is None:
            for m in out:
                out[m] = out[m] or ("no departure position and no GNSS or radar fix to place "
                                    "the frame (give --departure)")
    return out


def _method_kwargs(name: str, s: ReconstructSettings) -> dict[str, Any]:
    if name == "joint":
        from flightrecon.filters.joint import JointNoise, JointSettings

        try:
            noise = replace(JointNoise(), **(s.joint_noise or {}))
        except TypeError as exc:
            raise MetadataError(f"unknown joint noise setting: {exc}") from exc
        try:
            js = JointSettings(noise=noise, estimate_noise=s.joint_estimate_noise,
                               priors=tuple(tuple(p) for p in s.joint_priors or ()))
        except ValueError as exc:
            raise MetadataError(str(exc)) from exc
        return {"settings": js}
    if name == "sabziev":
        return {"k": s.k, "k_sd": s.k_sd, "strict": s.strict}
    if name == "arms":
        return {"form": s.arms_form, "linearisation": s.arms_linearisation}
    if name == "azimuth":
        return {"model": s.azimuth_model}
    if name == "sns":
        return {"model": s.sns_model, "form": s.sns_form, "noise_overrides": s.sns_noise}
    raise KeyError(name)


def run_method(name: str, clean: CleanFlight, settings: ReconstructSettings) -> MethodResult:
    """Run one estimator by name on a cleaned flight."""
    mod_name, fn_name = METHOD_FUNCTIONS[name]
    fn: Callable[..., MethodResult] = getattr(importlib.import_module(mod_name), fn_name)
    return fn(clean, **_method_kwargs(name, settings))
