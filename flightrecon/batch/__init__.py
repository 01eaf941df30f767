"""flightrecon.batch: fleet processing on Dask (many flights, one machine or a cluster).

Modules
-------
discover : which files are logs; output names confined to the output folder
task : :func:`run_flight`, the per-flight task a worker runs
manifest : input/settings fingerprints that make a batch resumable
cluster : :func:`open_client`, a LocalCluster sized to the machine or an existing scheduler
runner : :func:`batch`, the client side (store writer, manifests, summary tables)

See docs/batch.md.
"""

from flightrecon.batch.cluster import open_client
from flightrecon.batch.discover import LogEntry, discover_logs
from flightrecon.batch.runner import (
                                      AVERAGE_COLUMNS,
                                      FORMATS,
                                      SUMMARY_COLUMNS,
                                      SUMMARY_TYPES,
                                      BatchResult,
                                      FlightOutcome,
                                      batch,
                                      write_summary_parquet,
)
from flightrecon.batch.task import run_flight

__all__ = ["AVERAGE_COLUMNS", "FORMATS", "SUMMARY_COLUMNS", "SUMMARY_TYPES", "BatchResult",
           "FlightOutcome", "LogEntry", "batch", "discover_logs", "open_client", "run_flight",
           "write_summary_parquet"]
