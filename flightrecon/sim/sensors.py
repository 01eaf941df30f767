"""Sensor models and the multi-rate recorder (docs/simulator.md, "Sensors").

Each sensor is a small frozen dataclass whose fields are its documented error parameters; its
``record`` method turns truth rows into readings.  ``src`` are the truth rows the channel
actually samples (its own sample times, shifted by a clock offset when one is configured); the
recorder writes the readings at the channel's stamp rows.  Noise is white Gaussian unless said
otherwise; Gauss-Markov processes use the exact discretisation
``x_i = e^{-dt/tau} x_{i-1} + sigma sqrt(1 - e^{-2 dt/tau}) n_i`` started in its stationary law.
Quantisation rounds to the nearest multiple of the quantum (0 = none).  Error conventions follow
docs/schema.md, "Conventions": measured = true + error, a *correction* is true minus measured.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.signal import lfilter

from flightrecon.geo.wgs84 import WGS84_A, WGS84_E2
from flightrecon.errors import ValidationError
from flightrecon.geo.frames import TangentPlane
from flightrecon.sim.kinematics import dcm_body_to_ned
from flightrecon.types import Position

__all__ = [
    "AirspeedSensor",
    "ArmsRadar",
    "AttitudeSensor",
    "BaroSensor",
    "DopplerSensor",
    "Faults",
    "GnssReceiver",
    "LoadFactorSensor",
    "SensorSuite",
    "WindSensor",
    "first_order_lag",
    "gauss_markov",
    "quantise",
]

Interval = tuple[float, float]
"""(start_s, length_s)"""


def wrap360(x) -> np.ndarray:
    """Angle in [0, 360) (``np.mod`` alone returns 360.0 for tiny negative inputs)."""
    m = np.mod(np.asarray(x, float), 360.0)
    return np.where(m >= 360.0, 0.0, m)


def quantise(x: np.ndarray, quantum: float) -> np.ndarray:
    """Round to the nearest multiple of ``quantum`` (unchanged when ``quantum`` is 0)."""
    if quantum <= 0.0:
        return x
    return np.round(x / quantum) * quantum


def gauss_markov(n: int, dt_s: float, sigma: float, tau_s: float,
                 rng: np.random.Generator) -> np.ndarray:
    """First-order Gauss-Markov samples (stationary start), exact discretisation (module doc).

    ``dx/dt = -x / tau + sigma sqrt(2 / tau) w``; docs/arms.md.
    """
    if sigma == 0.0 or n == 0:
        return np.zeros(n)
    if tau_s <= 0.0:
        raise ValidationError("Gauss-Markov correlation time must be positive")
    phi = np.exp(-dt_s / tau_s)
    w = rng.standard_normal(n)
    w[1:] *= sigma * np.sqrt(1.0 - phi**2)
    w[0] *= sigma
    return lfilter([1.0], [1.0, -phi], w)


def first_order_lag(x: np.ndarray, dt_s: float, tau_s: float) -> np.ndarray:
    """First-order lag ``tau y' + y = x`` on a uniform grid, exact for a piecewise-linear input.

    ``y_k = a y_{k-1} + b0 x_k + b1 x_{k-1}`` with ``a = e^{-dt/tau}``,
    ``b0 = 1 - tau (1 - a) / dt``, ``b1 = tau (1 - a) / dt - a``; starts in equilibrium.
    """
    if tau_s <= 0.0:
        return np.asarray(x, float).copy()
    a = np.exp(-dt_s / tau_s)
    c = tau_s * (1.0 - a) / dt_s
    b0, b1 = 1.0 - c, c - a
    zi = np.array([x[0] * (1.0 - b0)])
    return lfilter([b0, b1], [1.0, -a], x, zi=zi)[0]


def _in_intervals(t: np.ndarray, intervals) -> np.ndarray:
    out = np.zeros(t.shape, bool)
    for start, length in intervals:
        out |= (t >= start) & (t < start + length)
    return out


@dataclass(frozen=True)
class LoadFactorSensor:
    """Body accelerometers, recorded as load factors ``n_long_g, n_lat_g, n_norm_g``.

    reading = (1 + scale) n + bias + noise, quantised, then clipped to the recorder's range
    ``range_g`` ((lo, hi) per axis; ``None``: unlimited): saturation.
    """

    rate_hz: float = 16.0
    bias_g: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: tuple[float, float, float] = (0.0, 0.0, 0.0)
    noise_sd_g: tuple[float, float, float] = (0.003, 0.003, 0.005)
    quantum_g: float = 0.0
    range_g: tuple[tuple[float, float], ...] | None = None

    group = "loads"

    def record(self, truth: pd.DataFrame, src: np.ndarray, rng: np.random.Generator,
               dt_s: float) -> dict[str, np.ndarray]:
        out = {}
        for i, col in enumerate(("n_long_g", "n_lat_g", "n_norm_g")):
            n = truth[col].to_numpy()[src]
            x = (1.0 + self.scale[i]) * n + self.bias_g[i] + self.noise_sd_g[i] * \
                rng.standard_normal(n.size)
            out[col] = quantise(x, self.quantum_g)
            if self.range_g is not None:
                out[col] = np.clip(out[col], *self.range_g[i])
        return out


@dataclass(frozen=True)
class AttitudeSensor:
    """Attitude and heading reference: roll, pitch, true heading.

    heading reading = heading + bias + noise (wrapped to [0, 360)); roll, pitch: + bias + noise.
    """

    rate_hz: float = 8.0
    roll_noise_sd_deg: float = 0.05
    pitch_noise_sd_deg: float = 0.05
    heading_noise_sd_deg: float = 0.1
    heading_bias_deg: float = 0.0
    quantum_deg: float = 0.0
    roll_bias_deg: float = 0.0
    pitch_bias_deg: float = 0.0

    group = "attitude"

    def record(self, truth, src, rng, dt_s):
        roll = truth["roll_deg"].to_numpy()[src] + self.roll_bias_deg + \
            self.roll_noise_sd_deg * rng.standard_normal(src.size)
        pitch = truth["pitch_deg"].to_numpy()[src] + self.pitch_bias_deg + \
            self.pitch_noise_sd_deg * rng.standard_normal(src.size)
        hdg = (truth["heading_deg"].to_numpy()[src] + self.heading_bias_deg
               + self.heading_noise_sd_deg * rng.standard_normal(src.size))
        return {"roll_deg": quantise(roll, self.quantum_deg),
                "pitch_deg": quantise(pitch, self.quantum_deg),
                "heading_deg": wrap360(quantise(hdg, self.quantum_deg))}


@dataclass(frozen=True)
class AirspeedSensor:
    """True airspeed from the air-data computer.

    reading = (1 + scale) lag(TAS) + noise; ``lag`` first-order with time constant ``lag_s``
    (:func:`first_order_lag`, on the truth grid before sampling); clipped to ``range_mps``
    (lo, hi) when given (the recorder's range: 0 below the instrument's lowest reading, hi
    at saturation).
    """

    rate_hz: float = 4.0
    scale: float = 0.0
    noise_sd_mps: float = 0.3
    lag_s: float = 0.5
    quantum_mps: float = 0.0
    range_mps: tuple[float, float] | None = None

    group = "airspeed"

    def record(self, truth, src, rng, dt_s):
        lagged = first_order_lag(truth["tas_mps"].to_numpy(), dt_s, self.lag_s)[src]
        x = (1.0 + self.scale) * lagged + self.noise_sd_mps * rng.standard_normal(src.size)
        x = quantise(np.maximum(x, 0.0), self.quantum_mps)
        if self.range_mps is not None:
            lo, hi = self.range_mps
            x = np.where(x < lo, 0.0, np.minimum(x, hi))
        return {"tas_mps": x}


@dataclass(frozen=True)
class BaroSensor:
    """Pressure altitude (1013.25 hPa datum) and static air temperature.

    baro reading = pressure altitude + bias + noise, quantised; SAT = SAT + noise, quantised.
    """

    rate_hz: float = 4.0
    bias_m: float = 0.0
    noise_sd_m: float = 1.5
    quantum_m: float = 0.3048
    sat_noise_sd_k: float = 0.2
    sat_quantum_k: float = 0.25

    group = "baro"

    def record(self, truth, src, rng, dt_s):
        h = (truth["pressure_alt_m"].to_numpy()[src] + self.bias_m
             + self.noise_sd_m * rng.standard_normal(src.size))
        sat = truth["sat_degc"].to_numpy()[src] + self.sat_noise_sd_k * \
            rng.standard_normal(src.size)
        return {"baro_alt_m": quantise(h, self.quantum_m),
                "sat_degc": quantise(sat, self.sat_quantum_k)}


@dataclass(frozen=True)
class GnssReceiver:
    """GNSS position (ellipsoidal height) and north/east velocity of the antenna.

    The antenna sits at ``lever_arm_m`` (body FRD) from the centre of mass: its NED offset is
    ``C_nb r`` and its velocity adds ``d(C_nb r)/dt`` (second-order central difference on the
    truth grid).  White noise: ``pos_sd_h_m`` on north and east, ``pos_sd_v_m`` up,
    ``vel_sd_mps`` per velocity component.  No fix inside ``dropouts`` ((start_s, length_s)).
    """

    rate_hz: float = 1.0
    pos_sd_h_m: float = 2.0
    pos_sd_v_m: float = 4.0
    vel_sd_mps: float = 0.1
    dropouts: tuple[Interval, ...] = ()
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)

    group = "gnss"

    def keep(self, t_s: np.ndarray) -> np.ndarray:
        """Stamp rows kept (outside the dropouts)."""
        return ~_in_intervals(t_s, self.dropouts)

    def record(self, truth, src, rng, dt_s):
        lat = truth["lat_deg"].to_numpy()
        h = truth["alt_m"].to_numpy()
        r = np.asarray(self.lever_arm_m, float)
        vn = truth["vn_mps"].to_numpy()
        ve = truth["ve_mps"].to_numpy()
        d_ned = np.zeros((lat.size, 3))
        if np.any(r != 0.0):
            c = dcm_body_to_ned(np.radians(truth["heading_deg"].to_numpy()),
                                np.radians(truth["pitch_deg"].to_numpy()),
                                np.radians(truth["roll_deg"].to_numpy()))
            d_ned = c @ r
            vn = vn + np.gradient(d_ned[:, 0], dt_s)
            ve = ve + np.gradient(d_ned[:, 1], dt_s)
        s2 = np.sin(np.radians(lat[src])) ** 2
        w = np.sqrt(1.0 - WGS84_E2 * s2)
        m_rad = WGS84_A * (1.0 - WGS84_E2) / w**3 + h[src]
        n_rad = WGS84_A / w + h[src]
        dn = d_ned[src, 0] + self.pos_sd_h_m * rng.standard_normal(src.size)
        de = d_ned[src, 1] + self.pos_sd_h_m * rng.standard_normal(src.size)
        du = -d_ned[src, 2] + self.pos_sd_v_m * rng.standard_normal(src.size)
        return {
            "gnss_lat_deg": lat[src] + np.degrees(dn / m_rad),
            "gnss_lon_deg": truth["lon_deg"].to_numpy()[src]
            + np.degrees(de / (n_rad * np.cos(np.radians(lat[src])))),
            "gnss_alt_m": h[src] + du,
            "gnss_vn_mps": vn[src] + self.vel_sd_mps * rng.standard_normal(src.size),
            "gnss_ve_mps": ve[src] + self.vel_sd_mps * rng.standard_normal(src.size),
        }


@dataclass(frozen=True)
class ArmsRadar:
    """Ground angle-range measuring system (ARMS) at ``station`` (MSL elevation of the antenna).

    Slant range, azimuth (clockwise from true north, ``atan2(east, north)`` in the station's
    tangent plane) and elevation angle, each with white Gaussian noise; one plot per scan
    (``scan_s``), time-stamped at the scan tick; none inside ``outages`` or beyond
    ``max_range_m``.  Azimuth wrapped to [0, 360).
    """

    station: Position
    geoid_undulation_m: float = 0.0
    scan_s: float = 4.0
    range_sd_m: float = 50.0
    azimuth_sd_deg: float = 0.25
    elevation_sd_deg: float = 0.1
    outages: tuple[Interval, ...] = ()
    max_range_m: float = 300e3

    group = "radar"

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.scan_s

    def keep(self, t_s: np.ndarray) -> np.ndarray:
        return ~_in_intervals(t_s, self.outages)

    def geometry(self, truth: pd.DataFrame, rows: np.ndarray):
        """Noise-free (slant range [m], azimuth [deg], elevation [deg]) at truth ``rows``."""
        tp = TangentPlane(float(self.station.lat_deg), float(self.station.lon_deg),
                          float(self.station.elev_m + self.geoid_undulation_m))
        e, n, u = tp.forward(truth["lat_deg"].to_numpy()[rows],
                             truth["lon_deg"].to_numpy()[rows], truth["alt_m"].to_numpy()[rows])
        rng_m = np.sqrt(e**2 + n**2 + u**2)
        return rng_m, wrap360(np.degrees(np.arctan2(e, n))), \
            np.degrees(np.arctan2(u, np.hypot(e, n)))

    def record(self, truth, src, rng, dt_s):
        r, az, el = self.geometry(truth, src)
        rr = r + self.range_sd_m * rng.standard_normal(src.size)
        aa = wrap360(az + self.azimuth_sd_deg * rng.standard_normal(src.size))
        ee = el + self.elevation_sd_deg * rng.standard_normal(src.size)
        far = r > self.max_range_m
        rr[far] = np.nan
        aa[far] = np.nan
        ee[far] = np.nan
        return {"arms_range_m": rr, "arms_azimuth_deg": aa, "arms_elevation_deg": ee}


@dataclass(frozen=True)
class DopplerSensor:
    """Doppler ground speed and drift angle (docs/sns.md).

    W~ = W (1 + scale) + noise; c~ = c + drift_bias + noise, c = track - heading (wrapped to
    (-180, 180]).
    """

    rate_hz: float = 4.0
    scale: float = 0.0
    drift_bias_deg: float = 0.0
    gs_noise_sd_mps: float = 0.3
    drift_noise_sd_deg: float = 0.1

    group = "doppler"

    def record(self, truth, src, rng, dt_s):
        w = truth["gs_mps"].to_numpy()[src]
        c = np.angle(np.exp(1j * np.radians(truth["track_deg"].to_numpy()[src]
                                           - truth["heading_deg"].to_numpy()[src])), deg=True)
        return {
            "doppler_gs_mps": np.maximum(w * (1.0 + self.scale) + self.gs_noise_sd_mps
                                         * rng.standard_normal(src.size), 0.0),
            "drift_deg": c + self.drift_bias_deg + self.drift_noise_sd_deg
            * rng.standard_normal(src.size),
        }


@dataclass(frozen=True)
class WindSensor:
    """Wind speed and direction (recorded or forecast), docs/sns.md:
    U~ = U + bias + GM + noise, from~ = from + bias + GM + noise.

    The Gauss-Markov parts (``*_gm_sd``, ``*_gm_tau_s``) run on the truth grid; their series
    are returned as truth (``wind_speed_err_gm_mps``, ``wind_from_err_gm_deg``).
    """

    rate_hz: float = 1.0
    speed_bias_mps: float = 0.0
    from_bias_deg: float = 0.0
    speed_gm_sd_mps: float = 0.0
    speed_gm_tau_s: float = 600.0
    from_gm_sd_deg: float = 0.0
    from_gm_tau_s: float = 600.0
    speed_noise_sd_mps: float = 0.5
    from_noise_sd_deg: float = 2.0

    group = "wind"

    def gm_series(self, n: int, dt_s: float, rng: np.random.Generator):
        """(speed error, direction error) Gauss-Markov series on the truth grid."""
        return (gauss_markov(n, dt_s, self.speed_gm_sd_mps, self.speed_gm_tau_s, rng),
                gauss_markov(n, dt_s, self.from_gm_sd_deg, self.from_gm_tau_s, rng))

    def record(self, truth, src, rng, dt_s, gm=None):
        wn = truth["wind_n_mps"].to_numpy()[src]
        we = truth["wind_e_mps"].to_numpy()[src]
        speed = np.hypot(wn, we)
        frm = np.degrees(np.arctan2(-we, -wn))
        gs, gd = gm if gm is not None else (np.zeros(truth.shape[0]),) * 2
        sp = speed + self.speed_bias_mps + gs[src] + self.speed_noise_sd_mps * \
            rng.standard_normal(src.size)
        fr = frm + self.from_bias_deg + gd[src] + self.from_noise_sd_deg * \
            rng.standard_normal(src.size)
        return {"wind_speed_mps": np.maximum(sp, 0.0), "wind_from_deg": wrap360(fr)}


@dataclass(frozen=True)
class Faults:
    """Defects injected to exercise cleaning (all recorded in the sensor truth).

    Attributes
    ----------
    spikes : number of single-sample spikes per listed channel
    spike_channels : ((column, size), ...): a spike adds +-size to one reading
    gaps : ((column, start_s, length_s), ...): readings removed (NaN)
    clock_offsets : ((group, offset_s), ...): the group's time stamps are ``offset_s`` late
        (the reading stamped t was taken at t - offset_s); rounded to the truth grid
    """

    spikes: int = 0
    spike_channels: tuple[tuple[str, float], ...] = ()
    gaps: tuple[tuple[str, float, float], ...] = ()
    clock_offsets: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class SensorSuite:
    """The sensors of one flight (``None`` = not fitted)."""

    loads: LoadFactorSensor = field(default_factory=LoadFactorSensor)
    attitude: AttitudeSensor = field(default_factory=AttitudeSensor)
    airspeed: AirspeedSensor = field(default_factory=AirspeedSensor)
    baro: BaroSensor = field(default_factory=BaroSensor)
    gnss: GnssReceiver | None = field(default_factory=GnssReceiver)
    radar: ArmsRadar | None = None
    doppler: DopplerSensor | None = None
    wind: WindSensor | None = None

    def fitted(self) -> tuple:
        """The fitted sensors, in a fixed order."""
        return tuple(s for s in (self.loads, self.attitude, self.airspeed, self.baro, self.gnss,
                                 self.radar, self.doppler, self.wind) if s is not None)
