"""Signals layer: time base, cleaning, resampling policy and flight phases.

Public API::

    clean_flight(flight, *, rate_hz=None, settings=CleaningSettings()) -> CleanFlight
    detect_phases(grid, settings=PhaseSettings(), *, lat_deg=45.0) -> FlightPhases

plus the composable steps (:class:`ResolveTimestamps`, :class:`UnwrapAngles`,
:class:`Despike`, :func:`run_steps`) and the per-channel tools they use.  The rules and their
numbers are in ``docs/signals.md``.
"""

from flightrecon.cleaning.despike import (
                                        DespikeSettings,
                                        despike_samples,
                                        estimate_quantum,
)
from flightrecon.cleaning.gaps import find_gaps, interpolate_with_gaps
from flightrecon.cleaning.phases import (
                                        PhaseSettings,
                                        detect_phases,
                                        detect_phases_with_report,
)
from flightrecon.cleaning.pipeline import CleaningSettings, clean_flight
from flightrecon.cleaning.resample import default_rate_hz, resample_inputs
from flightrecon.cleaning.steps import (
                                        CleaningStep,
                                        Despike,
                                        ResolveTimestamps,
                                        UnwrapAngles,
                                        run_steps,
)
from flightrecon.cleaning.timebase import (
                                        channel_samples,
                                        estimate_rate_hz,
                                        measurement_table,
                                        resolve_timestamps,
                                        uniform_grid,
)

__all__ = [
                                        "CleaningSettings",
                                        "CleaningStep",
                                        "Despike",
                                        "DespikeSettings",
                                        "PhaseSettings",
                                        "ResolveTimestamps",
                                        "UnwrapAngles",
                                        "channel_samples",
                                        "clean_flight",
                                        "default_rate_hz",
                                        "despike_samples",
                                        "detect_phases",
                                        "detect_phases_with_report",
                                        "estimate_quantum",
                                        "estimate_rate_hz",
                                        "find_gaps",
                                        "interpolate_with_gaps",
                                        "measurement_table",
                                        "resample_inputs",
                                        "resolve_timestamps",
                                        "run_steps",
                                        "uniform_grid",
]
