"""Helpers shared by the CLI commands (option parsing, default paths, progress)."""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import click

from flightrecon.errors import MetadataError


def input_options(f):
    """The options naming a flight's companion files: --gnss, --radar, --mapping, --sidecar."""
    path = click.Path(dir_okay=False, path_type=Path)
    for opt in reversed((
        click.option("--gnss", type=path, help="Separate GNSS file."),
        click.option("--radar", type=path, help="Separate radar (range/azimuth) file."),
        click.option("--mapping", type=path, help="Column-mapping TOML for a foreign log."),
        click.option("--sidecar", type=path,
                     help="Metadata TOML (default: <log stem>.meta.toml beside the log)."),
    )):
        f = opt(f)
    return f


def parse_k(text: str) -> tuple[float, float, float]:
    """Parse ``K1,K2,K3`` into three floats."""
    try:
        parts = [float(p) for p in text.split(",")]
    except ValueError as exc:
        raise MetadataError(f"--k expects three numbers K1,K2,K3, got '{text}'") from exc
    if len(parts) != 3 or not all(map(math.isfinite, parts)):
        raise MetadataError(f"--k expects three numbers K1,K2,K3, got '{text}'")
    return (parts[0], parts[1], parts[2])


def position_option_values(**opts: str | None) -> dict:
    """``{'departure': Position, ...}`` from ``LAT,LON,ELEV_M`` option strings."""
    from flightrecon.ingest import parse_position

    return {k: parse_position(v) for k, v in opts.items() if v}


def default_output(log: Path, suffix: str) -> Path:
    """A path beside ``log`` that never overwrites it: ``<stem><suffix>``."""
    stem = log.name
    for s in (".parquet", ".csv", ".pq"):
        if stem.lower().endswith(s):
            stem = stem[: -len(s)]
            break
    return log.with_name(stem + suffix)


@contextlib.contextmanager
def progress_bar(quiet: bool) -> Iterator[Callable[[str], None]]:
    """A stage progress display on stderr (tqdm); silent with ``quiet`` or when not a TTY."""
    if quiet or not sys.stderr.isatty():
        yield lambda name: None
        return
    from tqdm import tqdm

    bar = tqdm(total=None, desc="flightrecon", unit=" stage", file=sys.stderr, leave=False)
    try:
        def stage(name: str) -> None:
            bar.set_description(f"flightrecon: {name}")
            bar.update(1)
        yield stage
    finally:
        bar.close()


def read_sns_noise_file(path: Path) -> dict[str, float] | None:
    """The ``[sns]`` table of a noise TOML file (checked by the SNS method), or ``None``."""
    import tomllib

    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return None   # read_noise_file reports it
    t = doc.get("sns")
    if t is not None and not isinstance(t, dict):
        raise MetadataError("[sns] in the noise file must be a table", file=str(path))
    if t:
        from flightrecon.filters.sns_method import sns_noise_with
        from flightrecon.filters.sns import MODEL_AIRSPEED

        try:
            sns_noise_with(MODEL_AIRSPEED, t)   # keys and values checked now
        except MetadataError as exc:
            raise MetadataError(exc.message, file=str(path)) from None
    return dict(t) if t else None


def read_noise_file(path: Path) -> dict[str, float]:
    """The ``[joint]`` table of a noise TOML file: field name -> number (safe parser)."""
    import tomllib
    from dataclasses import fields

    from flightrecon.filters.joint import POSITIVE_NOISE, JointNoise

    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError as exc:
        raise MetadataError("noise file not found", file=str(path)) from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise MetadataError(f"not a valid TOML file: {exc}", file=str(path)) from exc
    table = doc.get("joint")
    if table is None and isinstance(doc.get("sns"), dict):
        return {}   # an SNS-only noise file (read_sns_noise_file)
    if not isinstance(table, dict):
        raise MetadataError("the noise file needs a [joint] or an [sns] table", file=str(path))
    known = {f.name for f in fields(JointNoise)}
    out = {}
    for k, v in table.items():
        if k not in known:
            raise MetadataError(f"unknown noise setting '{k}' (known: {', '.join(sorted(known))})",
                                file=str(path))
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise MetadataError(f"noise setting '{k}' must be a non-negative number",
                                file=str(path))
        if k in POSITIVE_NOISE and v == 0:
            raise MetadataError(f"noise setting '{k}' must be positive (a standard deviation of "
                                "zero would make its measurements exact)", file=str(path))
        out[k] = float(v)
    return out
