"""The door's physics checks: units and time base against physics, before any estimator runs.

Range checks (:mod:`flightrecon.ingest.validate`) catch values no aircraft can have; they
cannot catch a plausible number in the wrong unit: roll in radians in a ``_deg`` column never
leaves +-3.2 "degrees", a time column in milliseconds makes every rate 1000 times too small, a
pressure altitude in feet is only 3.28 times too large.  Each check here compares two channels
that physics ties together (the fits and their quality figures are in
:mod:`flightrecon.ingest.evidence`, each channel used at its own rate):

* **time unit**: the airspeed's change against the integrated longitudinal specific force
  ``g0 (n_long - sin(pitch))``, and the ground speed implied by consecutive GNSS positions
  against the recorded speeds; a factor near 1/1000 means milliseconds, 60 minutes;
* **attitude in radians**: roll, pitch and heading that never leave +-3.2 (0..6.3 for heading)
  are tested against ``n_long = sin(pitch) + dV/dt / g0`` (pitch) and against the GNSS track
  angle (heading); a channel that fits as radians and not as degrees is refused; all three in
  the radian range with nothing to test them against is a warning;
* **pressure altitude**: its vertical velocity changes as the vertical acceleration from the
  load factors and attitude integrates (``a_up = g0 (n_long sin th - n_lat sin phi cos th +
  n_norm cos phi cos th) - g0``; docs/schema.md, "Conventions"), with a factor between 0.8
  and 1.2 (pressure altitude against geometric height in a non-standard atmosphere); a factor
  near 3.28 is a feet column declared in metres, near 0.305 the reverse;
* **GNSS height against pressure altitude**: over the climbs and descents of a flight the two
  change together; a factor near 3.28 (or 0.305) is one of them in feet, and the vertical
  acceleration says which;
* **airspeed unit**: the true airspeed against coordinated turns (the heading turns at
  ``g0 tan(roll) / V``; no GNSS needed) and against the GNSS velocity through the wind
  triangle; a factor near 1.94 is knots in a m/s column, 0.51 m/s in a knots column;
* **sampling**: an input channel missing on most rows at irregular intervals (literal NaN
  where a value was due) is reported.

**A guess warns; only certainty refuses** (issue #34, docs/ingest.md, "The door").  A unit
refusal needs a fit of good quality (correlation, enough independent windows), a factor within
:data:`UNIT_BAND` of a known unit's factor whose uncertainty excludes the physical band, and,
where a second witness exists (GNSS height, GNSS velocity, a second fit), its agreement;
otherwise the suspicion is a warning that gives the evidence.  A unit the user declared
explicitly in a mapping file wins over the physics: it is used, with a loud warning giving the
factor found.  Every check leaves a :class:`DoorCheck` (figure and verdict: passed, warned,
refused, skipped) that ``flightrecon info`` lists.

A log too short to reconstruct is refused by :func:`check_reconstructable` with the minimum.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from flightrecon.errors import ValidationError
from flightrecon.ingest.door import RECONSTRUCT_INPUTS, DeclaredUnit, Door, DoorCheck
from flightrecon.ingest.unit_checks import (
    check_airspeed,
    check_attitude_units,
    check_baro,
    check_gnss_height,
    check_sampling,
    check_time_unit,
)

__all__ = [
    "MIN_DURATION_S",
    "MIN_INPUT_SAMPLES",
    "check_physics",
    "check_reconstructable",
    "door_checks",
]

#: a reconstruction needs at least this much record and this many samples of each input
MIN_DURATION_S = 30.0
MIN_INPUT_SAMPLES = 16


def door_checks(data: pd.DataFrame, prov, declared: Mapping[str, DeclaredUnit] | None = None
                ) -> tuple[list[str], list[DoorCheck]]:
    """Run every check of the module docstring on a merged, canonical flight table.

    Parameters
    ----------
    data : ``t_s`` and canonical channels in SI units (NaN where not sampled)
    prov : :class:`flightrecon.ingest.validate.Provenance` (files and source columns)
    declared : channel -> the unit its source column was read in (from the mapping)

    Returns
    -------
    warnings : suspicions that cannot be confirmed, and declared units the physics doubts
    checks : every check with its figure and verdict

    Raises
    ------
    DoorRefusal
        A unit mix-up the physics confirms, naming the file, the column, the likely unit and
        how to override it (a :class:`ValidationError`, exit 5).
    """
    door = Door(data, prov, declared or {})
    if data["t_s"].size < 8:
        door.record("physics", "-", "skipped", None, "fewer than 8 rows")
        return door.warnings, door.checks
    check_sampling(door)
    check_attitude_units(door)
    check_time_unit(door)
    baro = check_baro(door)
    check_gnss_height(door, baro)
    check_airspeed(door)
    return door.warnings, door.checks


def check_physics(data: pd.DataFrame, prov,
                  declared: Mapping[str, DeclaredUnit] | None = None) -> list[str]:
    """The warnings of :func:`door_checks` (raises as it does)."""
    return door_checks(data, prov, declared)[0]


# ------------------------------------------------------------------ sampling


# ------------------------------------------------------------------ length of the record


def check_reconstructable(flight) -> None:
    """Refuse a log too short to reconstruct, stating the minimum.

    A reconstruction needs :data:`MIN_DURATION_S` seconds of record and
    :data:`MIN_INPUT_SAMPLES` samples of each input channel it has: below that the take-off
    roll, the sensor biases and the filters' start-up cannot be told apart (a 10-row airborne
    log gave a track 9.9 km off).
    """
    d = flight.data
    file = flight.sources[0] if flight.sources else "the log"
    t = d["t_s"].to_numpy(dtype=float) if "t_s" in d.columns else np.array([])
    dur = float(t.max() - t.min()) if t.size else 0.0
    short = {c: int(d[c].notna().sum()) for c in RECONSTRUCT_INPUTS if c in d.columns
             and int(d[c].notna().sum()) < MIN_INPUT_SAMPLES}
    if dur < MIN_DURATION_S or short:
        what = f"{len(d)} rows over {dur:.3g} s"
        if short:
            what += "; " + ", ".join(f"{c} {n} samples" for c, n in short.items())
        raise ValidationError(
            f"the log is too short to reconstruct ({what}): the minimum is "
            f"{MIN_DURATION_S:g} s of record and {MIN_INPUT_SAMPLES} samples of each input "
            "channel", file=file)
