"""SNS method settings: the noise a user may override (``[sns]`` table of ``--noise``)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from flightrecon.errors import MetadataError
from flightrecon.methods import sns as core

#: SNS noise settings a user can override (``[sns]`` table of ``--noise``), in natural units
SNS_NOISE_KEYS = ("pos_sd_m", "vel_sd_mps", "speed_sd_mps", "heading_sd_deg", "wind_sd_mps",
                  "drift_sd_deg", "heading_bias_prior_deg")


def sns_noise_with(model: int, overrides: dict[str, float] | None) -> core.SnsNoise:
    """:func:`~flightrecon.methods.sns.default_noise` of ``model`` with ``overrides`` applied
    (keys :data:`SNS_NOISE_KEYS`: GNSS position / velocity sd per component, the speed reading's
    sd (TAS or Doppler ground speed), heading sd, wind reading sd (airspeed model), drift sd
    (Doppler model), the heading-bias prior).

    Raises
    ------
    MetadataError
        An unknown key, or a value that is not a positive number.
    """
    nz = core.default_noise(model)
    if not overrides:
        return nz
    sens = list(nz.sensor_sd)
    prior = list(nz.prior_sd)
    kw: dict = {}
    for k, v in overrides.items():
        if k not in SNS_NOISE_KEYS:
            raise MetadataError(f"unknown SNS noise setting '{k}' (known: "
                                f"{', '.join(SNS_NOISE_KEYS)})")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v <= 0:
            raise MetadataError(f"SNS noise setting '{k}' must be a positive number, got {v!r}")
        v = float(v)
        if k in ("pos_sd_m", "vel_sd_mps"):
            kw[k] = v
        elif k == "speed_sd_mps":
            sens[0] = v
        elif k == "heading_sd_deg":
            sens[1 if model == core.MODEL_AIRSPEED else 2] = float(np.deg2rad(v))
        elif k == "wind_sd_mps" and model == core.MODEL_AIRSPEED:
            sens[2] = sens[3] = v
        elif k == "drift_sd_deg" and model == core.MODEL_DOPPLER:
            sens[1] = float(np.deg2rad(v))
        elif k == "heading_bias_prior_deg":
            prior[2] = float(np.deg2rad(v))
    return replace(nz, sensor_sd=(sens[0], sens[1], sens[2], sens[3]),
                   prior_sd=(prior[0], prior[1], prior[2]), **kw)


@dataclass(frozen=True)
class SnsSettings:
    """Settings of the SNS method beyond its model, form and noise overrides (which are
    :class:`flightrecon.pipeline.ReconstructSettings` fields ``sns_model``, ``sns_form``,
    ``sns_noise``).

    Attributes
    ----------
    filter_rate_hz : rate of the filter grid [Hz] (:func:`flightrecon.methods.sns.method.solve_sns`)
    """

    filter_rate_hz: float = 2.0
