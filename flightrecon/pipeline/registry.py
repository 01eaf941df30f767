"""The method registry: which estimators exist, their settings (:class:`ReconstructSettings`),
when each can run on a flight and how it is called.

Each method is a :class:`MethodSpec`: its function, the class of its own settings (a field of
:class:`ReconstructSettings` named after the method; ``None`` there means that class's
defaults), the rule that says whether a flight's data allow it, and the keyword arguments it is
called with.  The settings class is imported only when needed, so importing the pipeline does
not import the estimators.
"""

from __future__ import annotations

import importlib
import types
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
from typing import TYPE_CHECKING, Any, Union, get_args, get_origin, get_type_hints

import pandas as pd

from flightrecon.errors import MetadataError
from flightrecon.types import CleanFlight, MethodResult

if TYPE_CHECKING:
    from flightrecon.methods.arms.method import ArmsSettings
    from flightrecon.methods.azimuth.method import AzimuthSettings
    from flightrecon.methods.joint import JointSettings
    from flightrecon.methods.sabziev.settings import SabzievSettings
    from flightrecon.methods.sns.settings import SnsSettings


@dataclass(frozen=True)
class ReconstructSettings:
    """Settings of one reconstruction: every method's, so that the run can be repeated from the
    summary (``summary["settings"]``, :meth:`to_dict` / :meth:`from_dict`).

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
        (:class:`flightrecon.methods.joint.JointNoise` field -> value), applied on top of
        ``joint.noise``
    joint_estimate_noise : scale each source's noise from the flight's own residuals (or
        ``joint.estimate_noise``)
    joint_gap_stretches : held-out stretches that calibrate the joint smoother's position sd
        inside GNSS gaps (``None``: ``joint.gap_stretches``; 0: off; docs/joint.md, "GNSS
        gaps")
    joint_priors : ``(error, mean, sd)`` priors of the joint smoother's sensor-error states
        (names of :data:`flightrecon.methods.joint.PRIOR_STATES`), e.g. an aircraft's fleet
        calibration (:func:`flightrecon.pipeline.fleet.fleet_settings`); replace ``joint.priors``
        when given
    strict : raise on the first method that fails, does not converge or is unhealthy
    keep_unhealthy : when no method is healthy, return (and let the CLI write) the unhealthy
        tracks under their prefixes for inspection instead of raising
        :class:`~flightrecon.errors.NoResultError`
    sns_noise : overrides of the SNS noise (:func:`flightrecon.methods.sns.settings.sns_noise_with`)
    start, end : trim the record to ``start <= t_s <= end`` before cleaning (seconds from the
        epoch or UTC timestamps; :func:`flightrecon.cleaning.trim.trim_flight`)
    joint, sabziev, arms, azimuth, sns : each method's own settings
        (:class:`~flightrecon.methods.joint.JointSettings`,
        :class:`~flightrecon.methods.sabziev.settings.SabzievSettings`,
        :class:`~flightrecon.methods.arms.method.ArmsSettings`,
        :class:`~flightrecon.methods.azimuth.method.AzimuthSettings`,
        :class:`~flightrecon.methods.sns.settings.SnsSettings`); ``None``: the defaults
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
    joint_gap_stretches: int | None = None
    joint_priors: tuple[tuple[str, float, float], ...] | None = None
    strict: bool = False
    keep_unhealthy: bool = False
    start: float | str | None = None
    end: float | str | None = None
    sns_noise: dict[str, float] | None = None
    joint: JointSettings | None = None
    sabziev: SabzievSettings | None = None
    arms: ArmsSettings | None = None
    azimuth: AzimuthSettings | None = None
    sns: SnsSettings | None = None

    def method_settings(self, name: str) -> Any:
        """The settings object of method ``name`` (its class's defaults where ``None``)."""
        s = getattr(self, name)
        return METHODS[name].settings_class()() if s is None else s

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-ready form (nested dataclasses as dicts, tuples as lists after
        ``json.dumps``); :meth:`from_dict` rebuilds an equal object."""
        return asdict(self)

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> ReconstructSettings:
        """The settings written by :meth:`to_dict` (also after a JSON round trip).

        Raises
        ------
        MetadataError
            An unknown field, or a method's settings that do not fit its class.
        """
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(doc) - known)
        if unknown:
            raise MetadataError(f"unknown reconstruction setting(s): {', '.join(unknown)}")
        hints = get_type_hints(cls, globalns=_settings_namespace())
        try:
            return cls(**{k: _rebuild(hints[k], v) for k, v in doc.items()})
        except (TypeError, ValueError) as exc:
            raise MetadataError(f"reconstruction settings do not fit: {exc}") from exc


def _settings_namespace() -> dict[str, Any]:
    """The methods' settings classes by name, for resolving :class:`ReconstructSettings`'s
    annotations (imports the method modules)."""
    ns: dict[str, Any] = dict(globals())
    for spec in METHODS.values():
        c = spec.settings_class()
        ns[c.__name__] = c
    return ns


def _rebuild(tp: Any, value: Any) -> Any:
    """``value`` (from :func:`dataclasses.asdict`, possibly through JSON) as type ``tp``:
    dataclasses from dicts, tuples from lists; other values as they are."""
    if value is None:
        return None
    origin = get_origin(tp)
    if origin in (Union, types.UnionType):
        options = [a for a in get_args(tp) if a is not type(None)]
        for a in options:
            if is_dataclass(a) and isinstance(value, Mapping):
                return _rebuild(a, value)
        for a in options:
            if get_origin(a) is tuple and isinstance(value, (list, tuple)):
                return _rebuild(a, value)
        return value
    if is_dataclass(tp) and isinstance(tp, type) and isinstance(value, Mapping):
        hints = get_type_hints(tp)
        names = {f.name for f in fields(tp)}
        extra = sorted(set(value) - names)
        if extra:
            raise TypeError(f"{tp.__name__} has no field(s) {', '.join(extra)}")
        return tp(**{k: _rebuild(hints[k], v) for k, v in value.items()})
    if origin is tuple and isinstance(value, (list, tuple)):
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_rebuild(args[0], v) for v in value)
        return tuple(_rebuild(a, v) for a, v in zip(args, value))
    if origin is dict and isinstance(value, Mapping):
        return dict(value)
    return value


@dataclass(frozen=True)
class MethodSpec:
    """One estimator: what it is called with and when it can run.

    Attributes
    ----------
    name : the method's name (its column prefix, its field of :class:`ReconstructSettings`)
    function : ``(module, function)`` of the estimator, ``fn(clean, **kwargs) -> MethodResult``
    settings_type : ``(module, class)`` of the method's own settings
    can_run : ``(clean, settings) -> None`` when the flight's data allow the method, else the
        reason it cannot run (the departure/origin rule common to all is applied after it)
    kwargs : ``(settings) -> dict``: the keyword arguments the function is called with
    """

    name: str
    function: tuple[str, str]
    settings_type: tuple[str, str]
    can_run: Callable[[CleanFlight, ReconstructSettings], str | None]
    kwargs: Callable[[ReconstructSettings], dict[str, Any]]

    def settings_class(self) -> type:
        """The class of the method's settings (imported on first use)."""
        mod, name = self.settings_type
        cls: type = getattr(importlib.import_module(mod), name)
        return cls

    def run(self, clean: CleanFlight, settings: ReconstructSettings) -> MethodResult:
        """Call the estimator (looked up at call time, so a patched module function is used)."""
        mod_name, fn_name = self.function
        fn: Callable[..., MethodResult] = getattr(importlib.import_module(mod_name), fn_name)
        return fn(clean, **self.kwargs(settings))


# -- when each method can run ------------------------------------------------------------------

def _joint_can_run(clean: CleanFlight, s: ReconstructSettings) -> str | None:
    from flightrecon.cleaning.dead import missing_inputs

    return missing_inputs(clean.grid, clean.report, (
        "n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg", "tas_mps"))


def _sabziev_can_run(clean: CleanFlight, s: ReconstructSettings) -> str | None:
    from flightrecon.cleaning.dead import missing_inputs
    from flightrecon.methods.sabziev.flight_inputs import REQUIRED_CHANNELS, end_fix

    missing = missing_inputs(clean.grid, clean.report, REQUIRED_CHANNELS)
    if missing:       # a dead channel is dropped by the cleaning (cleaning/dead.py)
        return missing
    if clean.meta.arrival is not None or s.k is not None or end_fix(clean) is not None:
        return None
    r = clean.meta.arrival_not_end
    if r is not None:    # given, but the record ends in the air
        return (f"the arrival given is not where the record ends (it ends in the air, "
                f"{r.height_above_field_m:.0f} m above that field at "
                f"{r.tas_mps:.0f} m/s) and no coefficients are given: give a --fix at the "
                "end of the record, or --k / fleet coefficients")
    return ("no arrival point and no coefficients (give --arrival, a --fix at the end of the "
            "record, or --k / fleet coefficients)")


def _radar_can_run(clean: CleanFlight, s: ReconstructSettings) -> str | None:
    if not (len(clean.radar) > 0 and "arms_azimuth_deg" in clean.radar.columns):
        return "no radar plots in the data"
    if clean.meta.station is None:
        return "radar plots but no station position (give --station)"
    return None


def _sns_can_run(clean: CleanFlight, s: ReconstructSettings) -> str | None:
    from flightrecon.cleaning.dead import missing_inputs

    has_gnss = len(clean.gnss) > 0 and "gnss_lat_deg" in clean.gnss.columns
    doppler = s.sns_model != "airspeed" and "doppler_gs_mps" in clean.grid.columns
    missing = missing_inputs(clean.grid, clean.report,
                             ("heading_deg", *(() if doppler else ("tas_mps",))))
    if has_gnss and missing:  # a dead channel is dropped by the cleaning (cleaning/dead.py)
        return missing
    if has_gnss:
        return None
    use = clean.meta.ingest.gnss_use.get("options") or {}
    return ("the GNSS withheld (--no-gnss or the sidecar's [gnss])" if use.get("withhold")
            else "no GNSS fixes in the data")


# -- how each method is called -----------------------------------------------------------------

def _joint_kwargs(s: ReconstructSettings) -> dict[str, Any]:
    base = s.method_settings("joint")
    try:
        noise = replace(base.noise, **(s.joint_noise or {}))
    except TypeError as exc:
        raise MetadataError(f"unknown joint noise setting: {exc}") from exc
    priors = base.priors if s.joint_priors is None else tuple(tuple(p) for p in s.joint_priors)
    try:
        js = replace(base, noise=noise, priors=priors,
                     estimate_noise=s.joint_estimate_noise or base.estimate_noise,
                     gap_stretches=(base.gap_stretches if s.joint_gap_stretches is None
                                    else int(s.joint_gap_stretches)))
    except ValueError as exc:
        raise MetadataError(str(exc)) from exc
    return {"settings": js}


def _sabziev_kwargs(s: ReconstructSettings) -> dict[str, Any]:
    return {"k": s.k, "k_sd": s.k_sd, "strict": s.strict, **asdict(s.method_settings("sabziev"))}


def _arms_kwargs(s: ReconstructSettings) -> dict[str, Any]:
    return {"form": s.arms_form, "linearisation": s.arms_linearisation,
            "settings": s.method_settings("arms")}


def _azimuth_kwargs(s: ReconstructSettings) -> dict[str, Any]:
    return {"model": s.azimuth_model, "settings": s.method_settings("azimuth")}


def _sns_kwargs(s: ReconstructSettings) -> dict[str, Any]:
    return {"model": s.sns_model, "form": s.sns_form, "noise_overrides": s.sns_noise,
            "filter_rate_hz": s.method_settings("sns").filter_rate_hz}


#: the estimators, in the order they are listed and (one thread) run
METHODS: dict[str, MethodSpec] = {
    "joint": MethodSpec("joint", ("flightrecon.methods.joint.method", "run_joint"),
                        ("flightrecon.methods.joint", "JointSettings"),
                        _joint_can_run, _joint_kwargs),
    "sabziev": MethodSpec("sabziev", ("flightrecon.methods.sabziev.method", "run_sabziev"),
                          ("flightrecon.methods.sabziev.settings", "SabzievSettings"),
                          _sabziev_can_run, _sabziev_kwargs),
    "arms": MethodSpec("arms", ("flightrecon.methods.arms.method", "run_arms"),
                       ("flightrecon.methods.arms.method", "ArmsSettings"),
                       _radar_can_run, _arms_kwargs),
    "azimuth": MethodSpec("azimuth", ("flightrecon.methods.azimuth.method", "run_azimuth"),
                          ("flightrecon.methods.azimuth.method", "AzimuthSettings"),
                          _radar_can_run, _azimuth_kwargs),
    "sns": MethodSpec("sns", ("flightrecon.methods.sns.method", "run_sns"),
                      ("flightrecon.methods.sns.settings", "SnsSettings"),
                      _sns_can_run, _sns_kwargs),
}

#: method name -> (module, function)
METHOD_FUNCTIONS: dict[str, tuple[str, str]] = {n: m.function for n, m in METHODS.items()}

ALL_METHODS: tuple[str, ...] = tuple(METHODS)

#: order in which methods supply the unprefixed horizontal track, sample by sample
DEFAULT_PRIORITY: tuple[str, ...] = ("joint", "sns", "arms", "sabziev", "azimuth")


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
    out = {name: spec.can_run(clean, settings) for name, spec in METHODS.items()}
    if meta.departure is None:
        out["sabziev"] = out["sabziev"] or ("no departure airfield (the fusion integrates from "
                                            "the lift-off point; give --departure)")
        if meta.origin is None:
            for m in out:
                out[m] = out[m] or ("no departure position and no GNSS or radar fix to place "
                                    "the frame (give --departure)")
    return out


def run_method(name: str, clean: CleanFlight, settings: ReconstructSettings) -> MethodResult:
    """Run one estimator by name on a cleaned flight."""
    return METHODS[name].run(clean, settings)
