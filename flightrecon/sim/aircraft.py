"""Aircraft: performance plus persistent sensor errors shared by all its flights.

Persistent errors (docs/simulator.md, "Aircraft and fleets") are what a per-aircraft coefficient
(Sabziev's k) or a per-aircraft sensor calibration would absorb: accelerometer bias and scale,
heading bias, airspeed scale, Doppler scale and drift bias, static-source (baro) bias, GNSS lever
arm.  :func:`draw_aircraft` draws them reproducibly from the aircraft id and a seed.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["JET", "LIGHT", "TURBOPROP", "Aircraft", "aircraft_seed", "draw_aircraft"]


@dataclass(frozen=True)
class Aircraft:
    """Performance [m/s, deg] and persistent sensor errors of one airframe.

    Attributes
    ----------
    rotate_tas_mps, climb_tas_mps, cruise_tas_mps, approach_tas_mps : true airspeeds
    climb_rate_mps, descent_rate_mps : vertical speeds in climb and en-route descent
    glide_rate_mps : vertical speed on final approach
    alpha_ref_deg, alpha_ref_tas_mps : 1 g angle of attack at a reference airspeed
    accel_bias_g, accel_scale : accelerometer bias [g] and scale error (long, lat, norm)
    heading_bias_deg : heading reference bias (reading minus true)
    roll_bias_deg, pitch_bias_deg : attitude reference biases (reading minus true); 0 unless a
        study sets them
    airspeed_scale : TAS scale error (reading = (1 + scale) TAS)
    doppler_scale, drift_bias_deg : Doppler ground-speed scale error and drift-angle bias
    baro_bias_m : static-source error as a pressure-altitude bias
    gnss_lever_arm_m : antenna position from the centre of mass, body FRD [m]
    """

    aircraft_id: str = "A1"
    rotate_tas_mps: float = 55.0
    climb_tas_mps: float = 65.0
    cruise_tas_mps: float = 70.0
    approach_tas_mps: float = 60.0
    climb_rate_mps: float = 4.0
    descent_rate_mps: float = 4.0
    glide_rate_mps: float = 3.0
    alpha_ref_deg: float = 4.0
    alpha_ref_tas_mps: float = 65.0
    accel_bias_g: tuple[float, float, float] = (0.003, -0.002, 0.004)
    accel_scale: tuple[float, float, float] = (0.002, 0.0, -0.003)
    heading_bias_deg: float = 0.8
    airspeed_scale: float = 0.02
    doppler_scale: float = 0.01
    drift_bias_deg: float = 0.4
    baro_bias_m: float = 5.0
    gnss_lever_arm_m: tuple[float, float, float] = (2.0, 0.0, -1.0)
    roll_bias_deg: float = 0.0
    pitch_bias_deg: float = 0.0


LIGHT = Aircraft()
"""A light twin for the circuit."""
TURBOPROP = Aircraft(aircraft_id="A2", rotate_tas_mps=60.0, climb_tas_mps=85.0, cruise_tas_mps=125.0,
                     approach_tas_mps=70.0, climb_rate_mps=7.0, descent_rate_mps=7.0,
                     glide_rate_mps=3.7, alpha_ref_deg=3.5, alpha_ref_tas_mps=90.0,
                     gnss_lever_arm_m=(5.0, 0.0, -1.5))
"""A regional turboprop."""
JET = Aircraft(aircraft_id="A3", rotate_tas_mps=80.0, climb_tas_mps=150.0, cruise_tas_mps=235.0,
               approach_tas_mps=75.0, climb_rate_mps=10.0, descent_rate_mps=10.0,
               glide_rate_mps=3.8, alpha_ref_deg=3.0, alpha_ref_tas_mps=150.0,
               gnss_lever_arm_m=(8.0, 0.0, -2.0))
"""A long-haul jet."""


def aircraft_seed(aircraft_id: str, seed: int) -> np.random.SeedSequence:
    """Seed sequence of an airframe: the fleet seed and a CRC-32 of its id."""
    return np.random.SeedSequence([int(seed), zlib.crc32(aircraft_id.encode("utf-8"))])


def draw_aircraft(aircraft_id: str, seed: int, base: Aircraft = TURBOPROP) -> Aircraft:
    """An airframe of type ``base`` with persistent errors drawn for ``aircraft_id``.

    Standard deviations: accelerometer bias 0.004 g, scale 0.003; heading bias 1 deg; airspeed
    scale 0.02; Doppler scale 0.01; drift bias 0.5 deg; baro bias 8 m; angle of attack +-10 %.
    """
    rng = np.random.Generator(np.random.PCG64(aircraft_seed(aircraft_id, seed)))
    z = rng.standard_normal(13)
    return replace(
        base, aircraft_id=aircraft_id,
        accel_bias_g=tuple(float(v) for v in 0.004 * z[0:3]),
        accel_scale=tuple(float(v) for v in 0.003 * z[3:6]),
        heading_bias_deg=float(1.0 * z[6]), airspeed_scale=float(0.02 * z[7]),
        doppler_scale=float(0.01 * z[8]), drift_bias_deg=float(0.5 * z[9]),
        baro_bias_m=float(8.0 * z[10]),
        alpha_ref_deg=float(base.alpha_ref_deg * (1.0 + 0.1 * np.tanh(z[11]))),
    )
