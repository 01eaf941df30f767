"""The result of a simulated flight (:class:`SimResult`): what every simulator returns."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pandas as pd

from flightrecon.types import FlightMeta


@dataclass(frozen=True, eq=False)
class SimResult:
    """A simulated flight.

    Attributes
    ----------
    log : recorded multi-rate log, canonical columns (what an estimator gets)
    truth : truth on the uniform truth grid (``t_s`` first; see docs/simulator.md)
    meta : flight metadata (what the sidecar carries)
    sensor_truth : persistent sensor errors, weather, events, injected faults (JSON-able)
    """

    log: pd.DataFrame
    truth: pd.DataFrame
    meta: FlightMeta
    sensor_truth: dict[str, Any]
