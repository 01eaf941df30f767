"""Wind conventions, once.

Recorded and forecast wind is meteorological: ``wind_from_deg`` is where it blows *from*,
clockwise from true north.  The models use the velocity of the air, which moves *toward*
``wind_from + 180 deg``::

    w_N = -speed cos(from),   w_E = -speed sin(from)

(docs/schema.md, "Conventions").  Ground velocity = air-relative velocity + w.
"""

from __future__ import annotations

import numpy as np


def wind_toward_ne(speed_mps, from_deg) -> np.ndarray:
    """North and east components [m/s], shape (N, 2), of the air's velocity for a wind of
    ``speed_mps`` blowing from ``from_deg`` (meteorological direction, degrees true)."""
    s = np.asarray(speed_mps, dtype=np.float64)
    f = np.radians(np.asarray(from_deg, dtype=np.float64))
    return np.column_stack([-s * np.cos(f), -s * np.sin(f)])


def wind_aloft_ne(levels, alt_msl_m) -> tuple[np.ndarray, np.ndarray]:
    """A winds-aloft table at the altitudes ``alt_msl_m`` (docs/wind.md, "The table").

    The levels' winds are turned into air velocities (:func:`wind_toward_ne`) and each
    component is interpolated linearly in altitude, held constant above the highest and below
    the lowest level (interpolating speed and direction instead would take the short way round
    or the long one arbitrarily between levels 180 deg apart).  The standard deviation is
    interpolated the same way.

    Parameters
    ----------
    levels : sequence of :class:`~flightrecon.types.WindLevel` (``alt_msl_m``, ``from_deg``,
        ``speed_mps``, ``sd_mps``), sorted by altitude (as ``read_wind_table`` returns them)
    alt_msl_m : altitudes MSL [m], shape (N,); NaN gives NaN

    Returns
    -------
    ne : (N, 2) north and east components of the air's velocity (where it moves to) [m/s]
    sd : (N,) standard deviation of each component [m/s]
    """
    z = np.asarray(alt_msl_m, dtype=np.float64).reshape(-1)
    za = np.array([lv.alt_msl_m for lv in levels], dtype=np.float64)
    w = wind_toward_ne([lv.speed_mps for lv in levels], [lv.from_deg for lv in levels])
    sd = np.array([lv.sd_mps for lv in levels], dtype=np.float64)
    ne = np.column_stack([np.interp(z, za, w[:, 0]), np.interp(z, za, w[:, 1])])
    s = np.interp(z, za, sd)
    bad = ~np.isfinite(z)
    ne[bad] = np.nan
    s[bad] = np.nan
    return ne, s
