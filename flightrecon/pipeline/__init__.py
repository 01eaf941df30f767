"""The reconstruction pipeline: the library API behind ``flightrecon reconstruct``.

Data flows one way::

    load_flight (ingest) -> clean_flight (cleaning) -> estimators -> combine -> export

Each estimator returns a :class:`flightrecon.types.MethodResult` whose columns carry its prefix
(``sabziev_``, ``arms_``, ``azimuth_``, ``sns_``).  The unprefixed default result is taken, per
sample, from the best available method (see :data:`DEFAULT_PRIORITY`) and the ``source`` column
records which one informed each sample.

Examples
--------
>>> from flightrecon.pipeline import reconstruct          # doctest: +SKIP
>>> rec = reconstruct("sample_logs/circuit.parquet")      # doctest: +SKIP
>>> rec.track[["t_s", "north_m", "east_m", "up_m"]]       # doctest: +SKIP
"""

from __future__ import annotations

from flightrecon.pipeline.combine import combine
from flightrecon.pipeline.health import method_health
from flightrecon.pipeline.registry import (
    ALL_METHODS,
    DEFAULT_PRIORITY,
    METHOD_FUNCTIONS,
    METHODS,
    MethodSpec,
    Reconstruction,
    ReconstructSettings,
    available_methods,
    run_method,
)
from flightrecon.pipeline.run import (
    default_workers,
    fleet_settings,
    reconstruct,
    reconstruct_clean,
    record_coefficients,
    record_flight,
)
from flightrecon.pipeline.summary import (
    SUMMARY_SCHEMA_VERSION,
    build_summary,
    sha256_file,
)

__all__ = [
    "METHOD_FUNCTIONS", "METHODS", "MethodSpec", "ALL_METHODS", "DEFAULT_PRIORITY",
    "ReconstructSettings",
    "Reconstruction", "available_methods", "run_method", "method_health", "combine",
    "SUMMARY_SCHEMA_VERSION", "sha256_file", "build_summary", "default_workers",
    "reconstruct_clean", "fleet_settings", "record_coefficients", "record_flight",
    "reconstruct",
]
