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
