"""The attitude reference's tilt noise of the joint smoother for one flight: from the attitude
source the sidecar declares and from what the flight's GNSS fixes measure (docs/joint.md, "The
attitude reference after sustained loads"; the model: :mod:`flightrecon.methods.joint.tilt`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from flightrecon.constants import G0 as G0_MPS2
from flightrecon.geo.kinematics import body_to_ned_matrix
from flightrecon.methods.joint.inputs import JointInputs
from flightrecon.methods.joint.settings import JointSettings
from flightrecon.methods.joint.tilt import erection_driver_g, remembered, tilt_evidence
from flightrecon.types import CleanFlight

#: the attitude reference's tilt noise for an attitude declared ``attitude_source = "ahrs"``
#: (methods/joint/tilt.py eq. 2: 1 m/s^2 per g of the erection driver, measured on the PH-LAB
#: AHRS; docs/realflights.md)
AHRS_TILT_MPS2_PER_G = 1.0

#: and the horizontal acceleration's share of its driver (tilt.py eq. 1b): 1, the aircraft's
#: whole acceleration (PH-LAB reference flight recorder only: 19.7 km RMS with the load's
#: departure alone, 3.8 km with it; docs/realflights.md)
AHRS_TILT_HORIZONTAL = 1.0

#: the remembered erection driver [g] (tilt.py eq. 1) above which an undeclared attitude source
#: is announced: below it the tilt noise would be a few tenths of m/s per minute
UNDECLARED_TILT_WARN_G = 0.1

#: a tilt gain measured by the GNSS below this [m/s^2 per g] is not used for an undeclared
#: source: JSBSim's attitude with its sensors' errors gives 0.04-0.18 on ten airwork, holding,
#: go-around, circuit, cross-country and jet flights, the PH-LAB AHRS 0.27 and 0.40
#: (docs/joint.md, "The attitude reference after sustained loads"); with 0.2 on JSBSim's
#: airwork (measured before the cubic fix velocities) a withheld 300 s gap went from 2 to 24 m
TILT_GAIN_MIN_MPS2_PER_G = 0.25


def gnss_tilt_evidence(clean: CleanFlight, inp: JointInputs,
                       settings: JointSettings) -> dict | None:
    """:func:`flightrecon.methods.joint.tilt.tilt_evidence` on the flight's GNSS fixes (those
    the smoother uses: withheld ones are not in ``inp.gnss``) between 30 s after the lift-off
    and 30 s before the touchdown (or the record's end); ``None`` without loads, fixes or a
    lift-off."""
    g = inp.gnss
    ph = clean.phases
    if (inp.f_body_g is None or g is None or len(g) < 10 or ph is None
            or not np.isfinite(ph.liftoff_t_s)):
        return None
    lat, lon = g["lat_deg"].to_numpy(float), g["lon_deg"].to_numpy(float)
    ok = np.isfinite(lat) & np.isfinite(lon)
    t_end = ph.touchdown_t_s if np.isfinite(ph.touchdown_t_s) else float(inp.t_in[-1])
    nz = settings.noise
    # on block means of about half a second (the windows are a minute long; a 10-hour, 16 Hz
    # record's regressors at full rate would be 150 MB)
    t = inp.t_in
    k = max(int(round(0.5 / float(np.median(np.diff(t))))), 1) if len(t) > 1 else 1
    nb = len(t) // k

    def blocks(x: np.ndarray) -> np.ndarray:  # NaN where a sample of the block is missing
        x = np.asarray(x, float)[:nb * k]
        return x.reshape((nb, k) + x.shape[1:]).mean(axis=1)

    tb, acc, fb = blocks(t), blocks(inp.acc_ned), blocks(inp.f_body_g)
    att = blocks(inp.attitude_deg[:, :2])
    psi = blocks(inp.heading_rad)
    C = body_to_ned_matrix(att[:, 0], att[:, 1], np.degrees(psi))
    f_ned_h = C[:, :2, :] * (fb * G0_MPS2)[:, None, :]
    return tilt_evidence(tb, acc, fb, psi, f_ned_h,
                         g["t_s"].to_numpy(float)[ok], lat[ok], lon[ok],
                         ph.liftoff_t_s + 30.0, t_end - 30.0, tau_s=nz.ahrs_tilt_tau_s,
                         window_s=nz.ahrs_tilt_tau_s,
                         horizontal=nz.ahrs_tilt_horizontal or AHRS_TILT_HORIZONTAL)


def tilt_noise_open(clean: CleanFlight, inp: JointInputs, settings: JointSettings) -> bool:
    """Whether the flight's tilt noise is still to be chosen (:func:`attitude_source_noise`):
    not where the sidecar declares an inertial reference, the settings give the gain, or the
    log has no loads; only then is the GNSS's measurement (:func:`gnss_tilt_evidence`) of
    use."""
    return not (clean.meta.attitude_source == "inertial"
                or settings.noise.ahrs_tilt_mps2_per_g > 0.0 or inp.f_body_g is None)


_MEASURE: dict = {}
"""Sentinel of :func:`attitude_source_noise`: measure the GNSS evidence there."""


def attitude_source_noise(clean: CleanFlight, inp: JointInputs, settings: JointSettings,
                          evidence: dict | None = _MEASURE
                          ) -> tuple[JointSettings, str | None]:
    """The tilt noise from the flight's declared attitude source and its GNSS (docs/joint.md,
    "The attitude reference after sustained loads").

    Settings that give the tilt gain win.  ``"inertial"`` leaves the settings (no tilt).
    Otherwise, where the GNSS fixes measure the gain (:func:`gnss_tilt_evidence`: the loads
    integrated through the attitude against the fixes' velocity, the constant biases removed),
    that gain is used, at most :data:`AHRS_TILT_MPS2_PER_G`, with the horizontal share
    :data:`AHRS_TILT_HORIZONTAL`, and the returned note says so (undeclared: only from
    :data:`TILT_GAIN_MIN_MPS2_PER_G`; below it the attitude is taken as inertial without a
    note, the fixes having shown it holds); ``"ahrs"`` without that
    evidence takes :data:`AHRS_TILT_MPS2_PER_G`.  Undeclared and unmeasured, the attitude is
    taken as inertial (off) and the note says so where the loads' remembered departure
    (tilt.py eq. 1) exceeds :data:`UNDECLARED_TILT_WARN_G` (a guess warns).  ``evidence``:
    :func:`gnss_tilt_evidence` already measured (``None``: none), measured here by default."""
    nz = settings.noise
    src = clean.meta.attitude_source
    if not tilt_noise_open(clean, inp, settings) or inp.f_body_g is None:  # (typed: no loads)
        return settings, None
    ev = gnss_tilt_evidence(clean, inp, settings) if evidence is _MEASURE else evidence
    if ev is not None:
        c = min(ev["gain_mps2_per_g"], AHRS_TILT_MPS2_PER_G)
        if c < TILT_GAIN_MIN_MPS2_PER_G and src is None:
            return settings, None  # the fixes show no load-driven error worth the noise
        note = (f"joint: the GNSS measures the attitude's load-driven error: the loads "
                f"integrated through the recorded attitude leave the fixes by "
                f"{ev['gain_mps2_per_g']:.2f} m/s^2 per g of sustained load ({ev['busy_windows']} "
                f"of {ev['windows']} windows of {ev['window_s']:.0f} s under load, constant "
                f"biases removed); the tilt noise is set to {c:.2f} m/s^2 per g "
                f"(attitude source {src or 'not declared'}; docs/joint.md)")
        return replace(settings, noise=replace(
            nz, ahrs_tilt_mps2_per_g=c,
            ahrs_tilt_horizontal=nz.ahrs_tilt_horizontal or AHRS_TILT_HORIZONTAL)), note
    if src == "ahrs":
        return replace(settings, noise=replace(
            nz, ahrs_tilt_mps2_per_g=AHRS_TILT_MPS2_PER_G,
            ahrs_tilt_horizontal=nz.ahrs_tilt_horizontal or AHRS_TILT_HORIZONTAL)), None
    D = remembered(inp.t_in, erection_driver_g(inp.f_body_g, inp.acc_ned,
                                               nz.ahrs_tilt_horizontal), nz.ahrs_tilt_tau_s)
    i = int(np.argmax(D)) if len(D) else 0
    if not len(D) or D[i] <= UNDECLARED_TILT_WARN_G:
        return settings, None
    return settings, (f"joint: attitude source not declared, taken as inertial (no tilt noise); "
                      f"the loads depart from 1 g by {D[i]:.2f} g over a minute at "
                      f"t = {inp.t_in[i]:.0f} s, where an attitude and heading reference "
                      "erects wrongly: declare [flight] attitude_source = \"ahrs\" or "
                      "\"inertial\" in the sidecar (docs/joint.md)")
