"""JSBSim as an independent truth source: the flight dynamics model, its weather and its state.

JSBSim (https://jsbsim.sourceforge.net, the ``jsbsim`` Python package, an optional extra:
``pip install 'flightrecon[jsbsim]'``) integrates a 6-DoF rigid body over a rotating WGS-84
Earth with its own aerodynamic, propulsion, ground-reaction, atmosphere and turbulence models.
Nothing here shares a model with the estimators (docs/jsbsim.md):

* load factors are JSBSim's specific force at the centre of gravity (all non-gravitational
  forces / mass, body axes), ``n = F / (m g0)``, ``n_norm = -F_z / (m g0)``, averaged over the
  JSBSim steps of each truth sample interval (the accelerometer's anti-aliasing filter: the
  gear's contact forces ring far above the recorder's rates; the average lags by half an
  interval);
* position (geodetic latitude, longitude, height above the ellipsoid, which JSBSim calls sea
  level), NED velocity over the Earth, Euler attitude (true heading), true airspeed, static
  pressure and temperature are JSBSim's own;
* the kinematic acceleration columns are the second-order central difference of the NED
  velocity on the truth grid (JSBSim's frame derivatives include Earth-rate terms that the
  project's relation leaves out: they are part of what an independent truth tests).

The mean wind is the project's :class:`~flightrecon.sim.weather.WindField` (height and time),
written into JSBSim at every control step; JSBSim adds its MIL-F-8785C turbulence (seeded),
and its standard atmosphere with a temperature offset and a sea-level pressure drifting in time.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass

import numpy as np

from flightrecon.errors import FlightReconError
from flightrecon.sim.weather import WindField

__all__ = ["FT", "AirframeModel", "Fdm", "FdmWeather", "import_jsbsim"]

FT = 0.3048
G0_FPS2 = 9.80665 / FT
KT = 1852.0 / 3600.0

STATE_PROPS = {
    "lat": "position/lat-geod-deg", "lon": "position/long-gc-deg", "h_ft": "position/h-sl-ft",
    "agl_ft": "position/h-agl-ft", "vn": "velocities/v-north-fps", "ve": "velocities/v-east-fps",
    "vd": "velocities/v-down-fps", "phi": "attitude/phi-deg", "theta": "attitude/theta-deg",
    "psi": "attitude/psi-deg", "p": "velocities/p-rad_sec", "q": "velocities/q-rad_sec",
    "r": "velocities/r-rad_sec", "beta": "aero/beta-deg", "alpha": "aero/alpha-deg",
    "vc": "velocities/vc-fps", "vt": "velocities/vtrue-fps", "fx": "forces/fbx-total-lbs",
    "fy": "forces/fby-total-lbs", "fz": "forces/fbz-total-lbs", "mass": "inertia/mass-slugs",
    "p_psf": "atmosphere/P-psf", "t_r": "atmosphere/T-R",
    "wn": "atmosphere/total-wind-north-fps", "we": "atmosphere/total-wind-east-fps",
    "wd": "atmosphere/total-wind-down-fps", "mach": "velocities/mach",
    "elev": "fcs/elevator-cmd-norm", "thr": "fcs/throttle-cmd-norm",
}
"""JSBSim properties read at every control step (feet, slugs, pounds as JSBSim has them)."""


def import_jsbsim():
    """The ``jsbsim`` module, or a clear error naming the extra that installs it."""
    try:
        import jsbsim
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise FlightReconError(
            "the JSBSim truth source needs the 'jsbsim' package: "
            "pip install 'flightrecon[jsbsim]'") from exc
    jsbsim.FGJSBBase().debug_lvl = 0  # no banner on stdout (the CLI's output is its own)
    return jsbsim


@dataclass(frozen=True)
class AirframeModel:
    """A JSBSim aircraft with what the autopilot needs to fly it.

    Speeds are calibrated airspeeds [m/s]; ``rest_agl_ft`` is the height of the centre of
    gravity above the runway at rest (where the model settles, measured); ``engines`` the number
    of throttles; ``gains`` the autopilot's loop gains (:class:`~flightrecon.sim.autopilot.Gains`).
    ``circuit_mps`` are the circuit's leg speeds (crosswind and downwind, base, the turn onto
    final, final intercept) and ``circuit_scale`` scales the circuit's distances (a faster
    aircraft turns wider); ``sensor_class`` picks the recorder's base performance and the
    spread of its persistent errors (``"light"`` or ``"jet"``, :mod:`flightrecon.sim.aircraft`).
    ``aircraft_class`` is a word for the tables (piston single, twin piston, turboprop, ...).
    ``start_each_engine``: magnetos on and every engine started by its own property (the
    packaged Cessna 310's piston engines do not run from the global start alone).
    ``prop_advance``: the propeller levers of a constant-speed propeller (JSBSim's
    ``fcs/advance-cmd-norm``; the Cessna 310's default 0 is the coarsest pitch: 1900 rpm at
    full throttle, too little power to climb and accelerate, and the pitch-on-speed loop
    pumped it into the ground); ``None`` leaves the model's default.
    ``climb_at_climb_speed``: a leg that climbs by more than the autopilot's level-change band
    flies at ``climb_mps`` until it is within the band (the trainers and jets: holding the
    pitch on a cruise speed they could not climb at, the level change dived them into the
    ground; the Cessna and the 737 fly as they always did, their records unchanged).
    """

    model: str
    engines: int
    rest_agl_ft: float
    vr_mps: float
    climb_mps: float
    cruise_mps: float
    approach_mps: float
    rotate_pitch_deg: float
    takeoff_flaps: float
    landing_flaps: float
    flare_ft: float
    climb_throttle: float
    idle_throttle: float
    gains: str
    brake: float = 0.6
    flare_pitch_deg: float = 5.0
    circuit_mps: tuple[float, float, float, float] = (40.0, 45.0, 38.0, 36.0)
    circuit_scale: float = 1.0
    sensor_class: str = "light"
    aircraft_class: str = "piston single"
    start_each_engine: bool = False
    climb_at_climb_speed: bool = False
    prop_advance: float | None = None


@dataclass(frozen=True)
class FdmWeather:
    """Weather of a JSBSim flight (drawn per seed by the scenarios).

    Attributes
    ----------
    wind : mean wind (height, time); JSBSim's turbulence adds to it
    turbulence_severity : MIL-F-8785C probability-of-exceedance index (0 none, 1 light,
        2 light-moderate, 3 moderate, ...), JSBSim's ``turb-type`` 3 (Tustin form)
    turbulence_wind_20ft_mps : wind speed at 20 ft that scales the low-altitude turbulence
    temp_offset_k : temperature offset from ISA at every height
    p_sl_hpa : sea-level pressure at t = 0; ``p_sl_rate_hpa_per_h`` its drift in time
    turbulence_seed : JSBSim's random seed
    """

    wind: WindField
    turbulence_severity: float = 1.0
    turbulence_wind_20ft_mps: float = 5.0
    temp_offset_k: float = 0.0
    p_sl_hpa: float = 1013.25
    p_sl_rate_hpa_per_h: float = 0.0
    turbulence_seed: int = 0


class Fdm:
    """One JSBSim flight: initial conditions at rest on a runway (or airborne, trimmed),
    weather applied at every control step, state read in SI.

    Parameters
    ----------
    airframe : the aircraft
    weather : weather
    lat_deg, lon_deg, elev_msl_m, heading_deg : start point (ground elevation) and heading
    dt_s : JSBSim's integration step
    airborne : ``(height_agl_m, cas_mps)`` to start trimmed in level flight, else ``None``
    full_tanks : fill every fuel tank (else the model's default load)
    """

    def __init__(self, airframe: AirframeModel, weather: FdmWeather, lat_deg: float,
                 lon_deg: float, elev_msl_m: float, heading_deg: float, dt_s: float,
                 airborne: tuple[float, float] | None = None, full_tanks: bool = False) -> None:
        jsbsim = import_jsbsim()
        self.airframe = airframe
        self.weather = weather
        f = jsbsim.FGFDMExec(None)
        f.set_debug_level(0)
        # the packaged Global 5000 declares a CSV log of its own, opened (header written) when
        # the model loads: into a scratch directory, then switched off
        with tempfile.TemporaryDirectory() as scratch:
            f.set_output_path(scratch)
            loaded = f.load_model(airframe.model)
            f.disable_output()
        if not loaded:  # pragma: no cover - the packaged models
            raise FlightReconError(f"JSBSim cannot load aircraft {airframe.model!r}")
        f.set_dt(dt_s)
        self.f = f
        self.dt_s = dt_s
        pm = f.get_property_manager()
        self._nodes = {k: pm.get_node(v, True) for k, v in STATE_PROPS.items()}
        self._wow = [pm.get_node(f"gear/unit[{i}]/WOW", True)
                     for i in range(f.get_ground_reactions().get_num_gear_units())]
        self._set = {k: pm.get_node(k, True) for k in (
            "atmosphere/wind-north-fps", "atmosphere/wind-east-fps", "atmosphere/P-sl-psf",
            "position/terrain-elevation-asl-ft")}
        self.terrain_m = elev_msl_m
        self._acc = [0.0, 0.0, 0.0, 0.0]
        f["atmosphere/randomseed"] = int(weather.turbulence_seed)
        f["atmosphere/delta-T"] = weather.temp_offset_k * 1.8
        f["atmosphere/P-sl-psf"] = self._psf(0.0)
        f["ic/lat-geod-deg"] = lat_deg
        f["ic/long-gc-deg"] = lon_deg
        f["ic/terrain-elevation-ft"] = elev_msl_m / FT
        f["ic/psi-true-deg"] = heading_deg
        if airborne is None:
            f["ic/h-agl-ft"] = airframe.rest_agl_ft
            f["ic/vt-fps"] = 0.0
        else:
            f["ic/h-agl-ft"] = airborne[0] / FT
            f["ic/vc-kts"] = airborne[1] / KT
        # full tanks on request (the packaged 737 starts with its centre tank a quarter full:
        # not enough for a three-hour flight)
        i = 0
        while full_tanks and pm.hasNode(f"propulsion/tank[{i}]/contents-lbs"):
            tank = f"propulsion/tank[{i}]/"
            if f[tank + "pct-full"] > 0.0:
                f[tank + "contents-lbs"] = f[tank + "contents-lbs"] * 100.0 / f[tank + "pct-full"]
            i += 1
        f.run_ic()
        f["atmosphere/turb-type"] = 3
        f["atmosphere/turbulence/milspec/severity"] = weather.turbulence_severity
        f["atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"] = \
            weather.turbulence_wind_20ft_mps / FT
        f["propulsion/set-running"] = -1
        if airframe.start_each_engine:
            f["propulsion/magneto_cmd"] = 3
            f["propulsion/starter_cmd"] = 1
            for i in range(airframe.engines):
                f[f"propulsion/engine[{i}]/set-running"] = 1
        for i in range(airframe.engines):
            sfx = "" if i == 0 else f"[{i}]"
            if airframe.prop_advance is not None:
                f[f"fcs/advance-cmd-norm{sfx}"] = airframe.prop_advance
            f[f"fcs/mixture-cmd-norm{sfx}"] = 1.0
            f[f"fcs/throttle-cmd-norm{sfx}"] = 0.0 if airborne is None else 0.6
        self.t0_s = 0.0
        self.apply_weather(0.0, elev_msl_m)
        if airborne is not None:
            f["simulation/do_simple_trim"] = 1

    # -- weather ------------------------------------------------------------------------------
    def _psf(self, t_s: float) -> float:
        w = self.weather
        return (w.p_sl_hpa + w.p_sl_rate_hpa_per_h * t_s / 3600.0) * 100.0 * 0.020885434

    def apply_weather(self, t_s: float, h_msl_m: float) -> None:
        """Mean wind at the aircraft's height and time, sea-level pressure at the time."""
        wn, we = self.weather.wind.velocity(np.array([h_msl_m]), np.array([t_s]))
        self._set["atmosphere/wind-north-fps"].set_double_value(float(wn[0]) / FT)
        self._set["atmosphere/wind-east-fps"].set_double_value(float(we[0]) / FT)
        self._set["atmosphere/P-sl-psf"].set_double_value(self._psf(t_s))

    def set_terrain(self, elev_msl_m: float) -> None:
        """Ground elevation under the aircraft (flat terrain at the nearer airfield)."""
        if elev_msl_m != self.terrain_m:
            self.terrain_m = elev_msl_m
            self._set["position/terrain-elevation-asl-ft"].set_double_value(elev_msl_m / FT)

    # -- stepping -----------------------------------------------------------------------------
    def run(self, steps: int) -> bool:
        """Integrate ``steps`` steps, summing the specific force of every step (for
        :meth:`mean_loads`); False if JSBSim stops."""
        f = self.f
        fx, fy, fz, m = (self._nodes[k] for k in ("fx", "fy", "fz", "mass"))
        acc = self._acc
        for _ in range(steps):
            if not f.run():
                return False
            w = m.get_double_value() * G0_FPS2
            acc[0] += fx.get_double_value() / w
            acc[1] += fy.get_double_value() / w
            acc[2] -= fz.get_double_value() / w
            acc[3] += 1.0
        return True

    def mean_loads(self) -> tuple[float, float, float] | None:
        """Load factors (long, lat, norm) averaged over the steps since the last call (the
        accelerometer's anti-aliasing: a boxcar over the sample interval); ``None`` before
        any step."""
        acc = self._acc
        if acc[3] == 0.0:
            return None
        out = (acc[0] / acc[3], acc[1] / acc[3], acc[2] / acc[3])
        self._acc = [0.0, 0.0, 0.0, 0.0]
        return out

    def set(self, prop: str, value: float) -> None:
        self.f[prop] = float(value)

    def throttle(self, value: float) -> None:
        for i in range(self.airframe.engines):
            self.f["fcs/throttle-cmd-norm" + ("" if i == 0 else f"[{i}]")] = float(value)

    def state(self) -> dict[str, float]:
        """The state in SI (m, m/s, deg, rad/s; ``n_*`` load factors, ``p_pa``, ``t_k``)."""
        v = {k: n.get_double_value() for k, n in self._nodes.items()}
        w = v["mass"] * G0_FPS2
        return {
            "t": self.f.get_sim_time() - self.t0_s, "lat": v["lat"], "lon": v["lon"],
            "h": v["h_ft"] * FT, "agl": v["agl_ft"] * FT, "vn": v["vn"] * FT, "ve": v["ve"] * FT,
            "vd": v["vd"] * FT, "phi": v["phi"], "theta": v["theta"], "psi": v["psi"] % 360.0,
            "p": v["p"], "q": v["q"], "r": v["r"], "beta": v["beta"], "alpha": v["alpha"],
            "vc": v["vc"] * FT, "vt": v["vt"] * FT, "n_long": v["fx"] / w, "n_lat": v["fy"] / w,
            "n_norm": -v["fz"] / w, "p_pa": v["p_psf"] * 47.880258889, "t_k": v["t_r"] / 1.8,
            "wn": v["wn"] * FT, "we": v["we"] * FT, "wd": v["wd"] * FT, "mach": v["mach"],
            "elev": v["elev"], "thr": v["thr"],
            "wow": any(n.get_double_value() > 0.5 for n in self._wow),
            "track": math.degrees(math.atan2(v["ve"], v["vn"])) % 360.0,
            "gs": math.hypot(v["vn"], v["ve"]) * FT,
        }

    def contact(self) -> bool:
        """Any contact point (gear or structure) on the ground."""
        return any(n.get_double_value() > 0.5 for n in self._wow)
