"""The method protocol of the pipeline (issue 20): each method declares its settings, when it
can run and how it is called; :class:`ReconstructSettings` holds every method's settings and
survives the trip through the summary (JSON); a numerical failure stays that method's."""

from __future__ import annotations

import json
from dataclasses import fields, is_dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from flightrecon.cleaning import clean_flight
from flightrecon.errors import MetadataError
from flightrecon.export.encode import to_json
from flightrecon.ingest import load_flight
from flightrecon.methods.arms.method import ArmsSettings
from flightrecon.methods.azimuth.method import AzimuthSettings
from flightrecon.methods.joint import JointNoise, JointSettings
from flightrecon.methods.sabziev.settings import SabzievSettings
from flightrecon.methods.sns.settings import SnsSettings
from flightrecon.pipeline import (
    ALL_METHODS,
    METHODS,
    ReconstructSettings,
    available_methods,
    reconstruct,
    reconstruct_clean,
)

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"

EVERY = ReconstructSettings(
    methods=("joint", "sns"), rate_hz=8.0, k=(0.1, -0.2, 0.3), k_sd=(0.01, 0.02, 0.03),
    arms_form="cascade", sns_noise={"pos_sd_m": 4.0}, joint_noise={"accel_bias_g": 0.002},
    joint_priors=(("tas_scale", 0.01, 0.02),), start="2024-01-01T10:00:00Z", end=600.0,
    joint=JointSettings(noise=JointNoise(wind_prior_mps=7.0), iterations=5,
                        noise_factor_bounds=(0.1, 10.0),
                        priors=(("heading_bias_deg", 1.0, 0.5),)),
    sabziev=SabzievSettings(hold="zero", tol_m=0.01, max_iter=7),
    arms=ArmsSettings(sigma_range_m=30.0, air_rate_hz=None),
    azimuth=AzimuthSettings(sigma_azimuth_deg=0.3, onboard_rate_hz=None),
    sns=SnsSettings(filter_rate_hz=4.0))


def test_every_method_declares_its_settings():
    """Each registered method names a settings dataclass, and ReconstructSettings has a field
    of that name whose ``None`` means that class's defaults."""
    names = {f.name for f in fields(ReconstructSettings)}
    assert tuple(METHODS) == ALL_METHODS
    for name, spec in METHODS.items():
        cls = spec.settings_class()
        assert is_dataclass(cls) and name in names
        assert ReconstructSettings().method_settings(name) == cls()
        assert EVERY.method_settings(name) == getattr(EVERY, name)


@pytest.mark.parametrize("settings", [ReconstructSettings(), EVERY], ids=["defaults", "every"])
def test_settings_round_trip_through_json(settings):
    """to_dict -> standard JSON (the summary file's) -> from_dict gives back an equal object
    (nested dataclasses, tuples)."""
    doc = json.loads(to_json(settings.to_dict()))   # the summary writer's JSON
    back = ReconstructSettings.from_dict(doc)
    assert back == settings
    assert isinstance(back.joint_priors, (tuple, type(None)))


def test_from_dict_names_what_does_not_fit():
    with pytest.raises(MetadataError, match="unknown reconstruction setting"):
        ReconstructSettings.from_dict({"no_such_setting": 1})
    with pytest.raises(MetadataError, match="ArmsSettings has no field"):
        ReconstructSettings.from_dict({"arms": {"sigma_range": 30.0}})
    with pytest.raises(MetadataError, match="joint prior"):
        ReconstructSettings.from_dict({"joint": {"priors": [["no_state", 0.0, 1.0]]}})


def test_summary_settings_repeat_the_run(monkeypatch):
    """The settings written into the summary rebuild the run's settings, and a method's own
    settings reach its function (here the Sabziev fusion's tolerance and iteration cap)."""
    import flightrecon.methods.sabziev.method as fm

    seen = {}
    real = fm.run_sabziev

    def spy(clean, **kwargs):
        seen.update(kwargs)
        return real(clean, **kwargs)

    monkeypatch.setattr(fm, "run_sabziev", spy)
    s = ReconstructSettings(methods=("sabziev",), sabziev=SabzievSettings(tol_m=0.01,
                                                                          max_iter=40))
    rec = reconstruct(SAMPLES / "circuit.csv", settings=s)
    assert seen["tol_m"] == 0.01 and seen["max_iter"] == 40 and seen["hold"] == "linear"
    doc = json.loads(to_json(rec.summary["settings"]))
    assert ReconstructSettings.from_dict(doc) == s


def test_can_run_rules_are_the_methods():
    """The availability rules come from the specs: a recorder-only flight runs the joint
    smoother and the Sabziev fusion, and says why the radar and GNSS methods cannot run."""
    clean = clean_flight(load_flight(SAMPLES / "circuit.csv"))
    clean = replace(clean, gnss=clean.gnss.iloc[:0], radar=clean.radar.iloc[:0])
    avail = available_methods(clean, ReconstructSettings())
    assert avail["joint"] is None and avail["sabziev"] is None
    assert avail["sns"] == "no GNSS fixes in the data"
    assert avail["arms"] == avail["azimuth"] == "no radar plots in the data"


@pytest.mark.parametrize("exc", [FloatingPointError("overflow encountered in exp"),
                                 ValueError("array must not contain infs or NaNs"),
                                 ZeroDivisionError("float division by zero"),
                                 np.linalg.LinAlgError("Matrix is not positive definite")])
def test_numerical_failure_in_one_method_is_its_error(monkeypatch, exc):
    """Regression (issue 20): a numerical breakdown inside one estimator is that method's
    ``failed`` status naming the exception; the other methods' results and the track stand."""
    import flightrecon.methods.sabziev.method as fm

    def broken(clean, **kwargs):
        raise exc

    monkeypatch.setattr(fm, "run_sabziev", broken)
    clean = clean_flight(load_flight(SAMPLES / "circuit.csv"))
    track, results, status = reconstruct_clean(
        clean, ReconstructSettings(methods=("joint", "sabziev")), workers=1)
    assert status["sabziev"]["status"] == "failed"
    assert type(exc).__name__ in status["sabziev"]["reason"]
    assert "joint" in results and "sabziev" not in results
    assert np.isfinite(track["north_m"]).any()
