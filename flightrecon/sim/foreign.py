"""A "foreign" recorder export: vendor column names, feet, knots, indicated airspeed, magnetic
heading and one flipped sign, with the mapping file that reads it back (docs/simulator.md,
"Foreign log").  The ingest engineer's mapping reader is the consumer; the mapping format is
shared (``[time]`` plus one ``[channels.<canonical>]`` table per channel).

Conversions (each exactly invertible):

* ``HDG_MAG = heading - declination`` (WMM, :func:`flightrecon.geo.magnetic.declination_deg`,
  at the aircraft's position on every row and the epoch's date; east positive), wrapped to
  [0, 360);
* ``IAS_KT = tas_to_cas(TAS, pressure altitude, SAT) / kt``, from the *recorded* TAS, baro
  altitude and SAT of the same row (IAS = CAS: no instrument or position error);
* ``ALT_FT = baro_alt_m / ft``; ``LATG = -n_lat_g`` (positive toward the left wing).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.constants import FOOT_M, KNOT_MPS
from flightrecon.errors import ValidationError
from flightrecon.geo.atmosphere import tas_to_cas
from flightrecon.geo.magnetic import decimal_year, declination_deg
from flightrecon.sim.sensors import wrap360

__all__ = ["FOREIGN_MAPPING_TOML", "foreign_log"]

FOREIGN_MAPPING_TOML = """\
# Column mapping of sample_logs/foreign.csv (flightrecon mapping format)
[time]
column = "TIME"
unit = "s"

[channels.n_norm_g]
column = "VRTG"
unit = "g"
sign = 1

[channels.n_long_g]
column = "LONG"
unit = "g"
sign = 1

[channels.n_lat_g]
column = "LATG"
unit = "g"
sign = -1

[channels.pitch_deg]
column = "PTCH"
unit = "deg"

[channels.roll_deg]
column = "ROLL"
unit = "deg"

[channels.heading_deg]
column = "HDG_MAG"
unit = "deg"
reference = "magnetic"

[channels.ias_mps]
column = "IAS_KT"
unit = "kt"

[channels.tas_mps]
from = "ias"

[channels.baro_alt_m]
column = "ALT_FT"
unit = "ft"

[channels.sat_degc]
column = "SAT"
unit = "degC"
"""


def foreign_log(log: pd.DataFrame, truth: pd.DataFrame, epoch_utc: str) -> pd.DataFrame:
    """Convert a single-rate canonical log (every row has every channel) to the foreign export.

    ``truth`` supplies the position for the declination at each row (the recorder's own
    magnetic heading would come from its flux valve at that position).

    Raises
    ------
    ValidationError
        If a needed channel is missing or not sampled on every row.
    """
    need = ("n_norm_g", "n_long_g", "n_lat_g", "pitch_deg", "roll_deg", "heading_deg",
            "tas_mps", "baro_alt_m", "sat_degc")
    for c in need:
        if c not in log or log[c].isna().any():
            raise ValidationError("the foreign export needs every channel on every row",
                                  column=c)
    tr = truth.set_index("t_s").loc[log["t_s"]]
    dec, _ = declination_deg(tr["lat_deg"].to_numpy(), tr["lon_deg"].to_numpy(),
                             tr["alt_m"].to_numpy(), decimal_year(epoch_utc, 0.0))
    cas = tas_to_cas(log["tas_mps"], log["baro_alt_m"], log["sat_degc"])
    return pd.DataFrame({
        "TIME": log["t_s"].to_numpy(),
        "VRTG": log["n_norm_g"].to_numpy(), "LONG": log["n_long_g"].to_numpy(),
        "LATG": -log["n_lat_g"].to_numpy(),
        "PTCH": log["pitch_deg"].to_numpy(), "ROLL": log["roll_deg"].to_numpy(),
        "HDG_MAG": wrap360(log["heading_deg"].to_numpy() - dec),
        "IAS_KT": np.asarray(cas) / KNOT_MPS,
        "ALT_FT": log["baro_alt_m"].to_numpy() / FOOT_M,
        "SAT": log["sat_degc"].to_numpy(),
    })
