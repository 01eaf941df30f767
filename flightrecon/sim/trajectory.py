"""Truth trajectory: a point-mass aircraft flown through smooth commands on the WGS-84 ellipsoid.

Construction (docs/simulator.md, "Trajectory"; plans are built by
:class:`flightrecon.sim.plan.PlanBuilder`):

* Commands are :class:`~flightrecon.sim.profiles.SmoothProfile` s (C2): ground speed on the
  ground ``G_cmd``, true airspeed ``V`` in the air, track rate ``chi_dot``, vertical speed ``v_u``,
  and smooth weights for air/ground (``b``), angle of attack and crab.
* Horizontal ground speed ``G = (1 - b) G_cmd + b G_air`` with
  ``G_air = w_par + sqrt(V_h^2 - w_perp^2)``, ``V_h^2 = V^2 - v_u^2``: the ground speed along
  the track ``chi`` for which ``|ground velocity - wind| = V`` (true airspeed held in the air).
* Kinematic acceleration in the local-level frame: ``a_N = G' cos chi - G sin chi chi_dot``,
  ``a_E = G' sin chi + G cos chi chi_dot``, ``a_U = v_u'`` (``G'`` by a central difference of the
  closed-form ``G`` with step 1e-4 s: truncation below 1e-8 m/s^2).
* Position: ``dlat/dt = v_N / (M + h)``, ``dlon/dt = v_E / ((N + h) cos lat)`` (meridian and
  prime-vertical radii of curvature), classical RK4 with the velocity at half steps (compiled);
  ``h`` is the closed-form integral of ``v_u``.
* Attitude: the body axes of a coordinated aircraft (no sideslip, n_lat = 0) at the angle of
  attack, about the air velocity (``track - drift``: air velocity + wind = ground velocity)
  except near the ground, where a smooth crab weight blends its direction to the ground track
  (no crab on the runway, de-crab in the flare)
  (:func:`~flightrecon.sim.kinematics.attitude_from_air`): wings level, heading = that
  direction and pitch = flight-path angle + angle of attack; in a bank the nose is off the air
  track by about alpha sin(roll), to the inside of the turn (before 2026-12-02 the heading was
  the air track and the pitch gamma + alpha in every bank, which no aircraft can fly).
* Load factors from the kinematic acceleration, the attitude and normal gravity
  (:func:`~flightrecon.sim.kinematics.loads_from_acceleration`).  Earth-rate and transport-rate
  terms are not in the project's load-factor relation and are not simulated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
import pandas as pd

from flightrecon.geo.wgs84 import WGS84_A, WGS84_E2
from flightrecon.errors import ValidationError
from flightrecon.geo.atmosphere import pressure_altitude_m
from flightrecon.geo.frames import TangentPlane
from flightrecon.geo.navframe import frame_rate_acceleration
from flightrecon.geo.gravity import normal_gravity
from flightrecon.sim.kinematics import attitude_from_air, loads_from_acceleration
from flightrecon.sim.profiles import SmoothProfile
from flightrecon.sim.weather import Atmosphere, WindField

__all__ = [
    "TRUTH_COLUMNS",
    "FlightPlan",
    "Kinematics",
    "kinematics",
    "simulate_truth",
]

DIFF_STEP_S = 1e-4
"""Step of the central difference for dG/dt (truncation ~ step^2 G'''/6 < 1e-8 m/s^2)."""

TRUTH_COLUMNS = (
    "t_s", "lat_deg", "lon_deg", "alt_m", "alt_msl_m", "north_m", "east_m", "up_m",
    "vn_mps", "ve_mps", "vu_mps", "an_mps2", "ae_mps2", "au_mps2",
    "roll_deg", "pitch_deg", "heading_deg", "tas_mps", "wind_n_mps", "wind_e_mps",
    "pressure_alt_m", "on_ground",
    "n_long_g", "n_lat_g", "n_norm_g", "track_deg", "gs_mps", "alpha_deg", "sat_degc",
    "static_pressure_pa", "gravity_mps2",
)


@dataclass(frozen=True, eq=False)
class FlightPlan:
    """Everything that defines a truth trajectory (built by :class:`PlanBuilder`).

    Attributes
    ----------
    t_end_s : duration [s]
    lat0_deg, lon0_deg : start point
    geoid_undulation_m : ellipsoidal minus MSL height, constant over the flight [m]
    h0_msl_m : start height above MSL [m]
    track0_deg : start ground track [deg]
    ground_speed, tas, turn_rate, vertical_speed : command profiles [m/s, m/s, rad/s, m/s]
    air_weight, alpha_weight, crab_weight : smooth weights in [0, 1]
    alpha_ref_deg, alpha_ref_tas_mps : angle of attack at the reference airspeed in 1 g flight;
        alpha = alpha_ref (V_ref / V)^2
    liftoff_s, touchdown_s : events (NaN when the record starts / ends airborne)
    wind, atmosphere : weather
    """

    t_end_s: float
    lat0_deg: float
    lon0_deg: float
    geoid_undulation_m: float
    h0_msl_m: float
    track0_deg: float
    ground_speed: SmoothProfile
    tas: SmoothProfile
    turn_rate: SmoothProfile
    vertical_speed: SmoothProfile
    air_weight: SmoothProfile
    alpha_weight: SmoothProfile
    crab_weight: SmoothProfile
    alpha_ref_deg: float
    alpha_ref_tas_mps: float
    liftoff_s: float
    touchdown_s: float
    wind: WindField
    atmosphere: Atmosphere


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Closed-form kinematics at given times (arrays of one shape); SI, angles in radians."""

    t_s: np.ndarray
    h_msl_m: np.ndarray
    vu_mps: np.ndarray
    au_mps2: np.ndarray
    track_rad: np.ndarray
    track_rate_rps: np.ndarray
    gs_mps: np.ndarray
    vn_mps: np.ndarray
    ve_mps: np.ndarray
    an_mps2: np.ndarray
    ae_mps2: np.ndarray
    wind_n_mps: np.ndarray
    wind_e_mps: np.ndarray


def _ground_speed(plan: FlightPlan, t: np.ndarray):
    """Horizontal ground speed G(t) (module docstring), plus track and height pieces."""
    vu, au, dh = plan.vertical_speed.evaluate(t)
    h = plan.h0_msl_m + dh
    rate, _, dchi = plan.turn_rate.evaluate(t)
    chi = np.radians(plan.track0_deg) + dchi
    b = plan.air_weight.value(t)
    g_cmd = plan.ground_speed.value(t)
    wn, we = plan.wind.velocity(h, t)
    gs = g_cmd.copy()
    air = b > 0.0
    if np.any(air):
        v = plan.tas.value(t[air])
        c, s = np.cos(chi[air]), np.sin(chi[air])
        w_par = wn[air] * c + we[air] * s
        w_perp = -wn[air] * s + we[air] * c
        disc = v**2 - vu[air] ** 2 - w_perp**2
        if np.any(disc <= 0.0):
            raise ValidationError("simulated airspeed is below the crosswind plus climb rate: "
                                  "raise the airspeed or lower the wind")
        g_air = w_par + np.sqrt(disc)
        gs[air] = (1.0 - b[air]) * g_cmd[air] + b[air] * g_air
    return gs, chi, rate, h, vu, au, wn, we


def kinematics(plan: FlightPlan, t_s) -> Kinematics:
    """Evaluate the plan's kinematics at times ``t_s`` (1-D array) [s]."""
    t = np.ascontiguousarray(np.asarray(t_s, float).ravel())
    gs, chi, rate, h, vu, au, wn, we = _ground_speed(plan, t)
    gp = _ground_speed(plan, t + DIFF_STEP_S)[0]
    gm = _ground_speed(plan, t - DIFF_STEP_S)[0]
    gdot = (gp - gm) / (2.0 * DIFF_STEP_S)
    c, s = np.cos(chi), np.sin(chi)
    return Kinematics(
        t_s=t, h_msl_m=h, vu_mps=vu, au_mps2=au, track_rad=chi, track_rate_rps=rate,
        gs_mps=gs, vn_mps=gs * c, ve_mps=gs * s,
        an_mps2=gdot * c - gs * s * rate, ae_mps2=gdot * s + gs * c * rate,
        wind_n_mps=wn, wind_e_mps=we,
    )


@numba.njit(cache=True)
def _rk4_geodetic(lat0, lon0, dt, vn, ve, h, a, e2, out_lat, out_lon):
    """RK4 for dlat/dt = vn/(M+h), dlon/dt = ve/((N+h) cos lat); inputs at half steps."""
    n = out_lat.shape[0]
    lat = lat0
    lon = lon0
    out_lat[0] = lat
    out_lon[0] = lon
    for k in range(n - 1):
        i0 = 2 * k
        k1a = 0.0
        k1o = 0.0
        k2a = 0.0
        k2o = 0.0
        k3a = 0.0
        k3o = 0.0
        k4a = 0.0
        k4o = 0.0
        for stage in range(4):
            if stage == 0:
                la = lat
                j = i0
            elif stage == 1:
                la = lat + 0.5 * dt * k1a
                j = i0 + 1
            elif stage == 2:
                la = lat + 0.5 * dt * k2a
                j = i0 + 1
            else:
                la = lat + dt * k3a
                j = i0 + 2
            s2 = np.sin(la) ** 2
            w = np.sqrt(1.0 - e2 * s2)
            m = a * (1.0 - e2) / (w * w * w)
            nn = a / w
            da = vn[j] / (m + h[j])
            do = ve[j] / ((nn + h[j]) * np.cos(la))
            if stage == 0:
                k1a, k1o = da, do
            elif stage == 1:
                k2a, k2o = da, do
            elif stage == 2:
                k3a, k3o = da, do
            else:
                k4a, k4o = da, do
        lat += dt / 6.0 * (k1a + 2.0 * k2a + 2.0 * k3a + k4a)
        lon += dt / 6.0 * (k1o + 2.0 * k2o + 2.0 * k3o + k4o)
        out_lat[k + 1] = lat
        out_lon[k + 1] = lon


def _wrap360(x):
    m = np.mod(x, 360.0)
    return np.where(m >= 360.0, 0.0, m)


def simulate_truth(plan: FlightPlan, rate_hz: float, plane: TangentPlane) -> pd.DataFrame:
    """Sample the truth on a uniform grid ``t = k / rate_hz``, ``k = 0 .. t_end * rate``.

    Parameters
    ----------
    plan : the flight plan
    rate_hz : truth rate (the fastest recorded channel's rate) [Hz]
    plane : output tangent plane (:func:`flightrecon.geo.frames.output_plane`)

    Returns
    -------
    DataFrame with :data:`TRUTH_COLUMNS` (``t_s`` first; SI; angles in degrees).
    """
    if rate_hz <= 0 or plan.t_end_s <= 0:
        raise ValidationError("truth rate and duration must be positive")
    n = round(plan.t_end_s * rate_hz) + 1
    dt = 1.0 / rate_hz
    t_half = np.arange(2 * n - 1) * (0.5 * dt)
    kin_half = kinematics(plan, t_half)
    h_ell_half = kin_half.h_msl_m + plan.geoid_undulation_m
    lat = np.empty(n)
    lon = np.empty(n)
    _rk4_geodetic(np.radians(plan.lat0_deg), np.radians(plan.lon0_deg), dt,
                  np.ascontiguousarray(kin_half.vn_mps), np.ascontiguousarray(kin_half.ve_mps),
                  np.ascontiguousarray(h_ell_half), WGS84_A, WGS84_E2, lat, lon)
    sl = slice(0, None, 2)
    t = t_half[sl]
    h_msl = kin_half.h_msl_m[sl]
    h_ell = h_msl + plan.geoid_undulation_m
    lat_deg = np.degrees(lat)
    lon_deg = np.degrees(lon)
    vn, ve, vu = kin_half.vn_mps[sl], kin_half.ve_mps[sl], kin_half.vu_mps[sl]
    an, ae, au = kin_half.an_mps2[sl], kin_half.ae_mps2[sl], kin_half.au_mps2[sl]
    wn, we = kin_half.wind_n_mps[sl], kin_half.wind_e_mps[sl]
    chi = kin_half.track_rad[sl]

    # attitude
    air_n, air_e = vn - wn, ve - we
    air_h = np.hypot(air_n, air_e)
    tas = np.sqrt(air_h**2 + vu**2)
    crab = plan.crab_weight.value(t)
    wca = np.where(crab > 0.0, np.angle(np.exp(1j * (np.arctan2(air_e, air_n) - chi))), 0.0)
    heading = chi + crab * wca
    gamma = np.arctan2(vu, air_h)
    v_for_alpha = np.maximum(tas, 0.6 * plan.alpha_ref_tas_mps)
    alpha = (plan.alpha_weight.value(t) * np.radians(plan.alpha_ref_deg)
             * (plan.alpha_ref_tas_mps / v_for_alpha) ** 2)
    g = normal_gravity(lat_deg, h_ell)
    # what the accelerometers sense: the velocity's rate less the frame's rotation (Coriolis
    # and transport rate: dv/dt = f + g - (2 omega_ie + omega_en) x v, docs/simulator.md)
    a_ned = np.column_stack([an, ae, -au]) - frame_rate_acceleration(
        lat_deg, h_ell, np.column_stack([vn, ve, -vu]))
    # the body axes: the air velocity's (crabbed on the ground) pitched up by alpha, banked
    # for no sideslip; in a bank the nose is off the air track by about alpha sin(roll)
    heading, pitch, roll = attitude_from_air(heading, gamma, alpha, a_ned, g)
    loads = loads_from_acceleration(a_ned, g, heading, pitch, roll)

    east, north, up = plane.forward(lat_deg, lon_deg, h_ell)
    p_static = plan.atmosphere.pressure_pa(h_msl, t)
    on_ground = np.zeros(n, bool)
    if np.isfinite(plan.liftoff_s):
        on_ground |= t < plan.liftoff_s
    if np.isfinite(plan.touchdown_s):
        on_ground |= t >= plan.touchdown_s
    cols = {
        "t_s": t, "lat_deg": lat_deg, "lon_deg": lon_deg, "alt_m": h_ell, "alt_msl_m": h_msl,
        "north_m": north, "east_m": east, "up_m": up,
        "vn_mps": vn, "ve_mps": ve, "vu_mps": vu, "an_mps2": an, "ae_mps2": ae, "au_mps2": au,
        "roll_deg": np.degrees(roll), "pitch_deg": np.degrees(pitch),
        "heading_deg": _wrap360(np.degrees(heading)), "tas_mps": tas,
        "wind_n_mps": wn, "wind_e_mps": we,
        "pressure_alt_m": pressure_altitude_m(p_static), "on_ground": on_ground,
        "n_long_g": loads[:, 0], "n_lat_g": loads[:, 1], "n_norm_g": loads[:, 2],
        "track_deg": _wrap360(np.degrees(chi)), "gs_mps": kin_half.gs_mps[sl],
        "alpha_deg": np.degrees(alpha),
        "sat_degc": plan.atmosphere.temperature_k(h_msl) - 273.15,
        "static_pressure_pa": p_static, "gravity_mps2": g,
    }
    return pd.DataFrame({k: np.asarray(cols[k]) for k in TRUTH_COLUMNS})
