"""The project's own fuzzer: a seeded list of mutations of the shipped sample logs.

Content (swapped, repeated, conflicting and missing rows, clock resets and jumps, values in
another unit, spikes, NaN, text, infinities, truncation, dropped, renamed, negated and frozen
columns), encoding (UTF-16, Windows-1252, BOM, CRLF, other delimiters, NUL bytes, binary,
truncated bytes), metadata (sidecar and mapping missing, malformed or hostile), outputs (over an
input, over each other, missing or unwritable folders, empty paths) and signals (SIGINT, SIGTERM
at several moments) are applied to ``handmade.csv``, ``circuit.parquet`` and ``foreign.csv``
and run through ``info``, ``clean`` and ``reconstruct`` in-process (subprocesses only for
the signals).  Every case must give:

* a documented exit code (README) and never 1 (an internal error) nor a traceback;
* a message naming a file of the case when the input is refused (codes 3 to 10);
* no input modified, no temporary file or staging folder left;
* exit 0 only with a finite, physically possible result: time increasing, positions finite on
  most of the record, speeds between samples below 400 m/s, heights within -1 to 20 km.

The list is fixed by ``SEED`` (reproducible in CI); ``FLIGHTRECON_FUZZ_SEED`` gives another
list of the same size for exploration.  163 in-process cases and 6 signal cases; measured
56-61 s with ``-n 2`` on a shared 2-core machine (load average 13), warm kernel cache.

The faults of issue #39 (a misspelt mapping key or table, a derived channel without its source,
impossible mapping combinations, nested Parquet columns, read-only or foreign stores, output
folders that cannot be written) follow as 23 more cases, each with the exit code it must give
and the words (file, table, key) its message must hold.
"""

from __future__ import annotations

import hashlib
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.cli.main import main
from flightrecon.export.atomic import TMP_TAG

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"
SEED = int(os.environ.get("FLIGHTRECON_FUZZ_SEED", "24"))
DOCUMENTED = {0, 2, 3, 4, 5, 6, 7, 8, 9, 10, 130, 143}

HANDMADE = pd.read_csv(SAMPLES / "handmade.csv")


@dataclass
class Case:
    """One fuzz case: how to build its folder and which command to run."""

    name: str
    command: str                       # info | clean | reconstruct
    build: Callable[[Path, random.Random], tuple[Path, list]]   # -> (log, extra args)
    seed: int
    out_args: Callable[[Path, Path], list] | None = None      # (folder, log) -> output args
    tags: set[str] = field(default_factory=set)
    #: exit code the case must give and words its message must hold (the file, the key)
    expect: tuple[int, tuple[str, ...]] | None = None
    #: (folder, monkeypatch) -> None: the environment of the case (a read-only store)
    env: Callable[[Path, pytest.MonkeyPatch], None] | None = None


# ------------------------------------------------------------------ builders


def _copy_meta(d: Path, stem: str, src: str = "handmade") -> None:
    shutil.copy(SAMPLES / f"{src}.meta.toml", d / f"{stem}.meta.toml")


def frame_case(mutate: Callable[[pd.DataFrame, random.Random], pd.DataFrame],
               meta: bool = True) -> Callable:
    def build(d: Path, rng: random.Random):
        df = mutate(HANDMADE.copy(), rng)
        p = d / "log.csv"
        df.to_csv(p, index=False)
        if meta:
            _copy_meta(d, "log")
        return p, []
    return build


def text_case(mutate: Callable[[str, random.Random], bytes | str], name: str = "log.csv",
              meta: bool = True) -> Callable:
    def build(d: Path, rng: random.Random):
        text = (SAMPLES / "handmade.csv").read_text(encoding="utf-8")
        data = mutate(text, rng)
        p = d / name
        if isinstance(data, str):
            p.write_text(data, encoding="utf-8", newline="")
        else:
            p.write_bytes(data)
        if meta:
            _copy_meta(d, Path(name).name.split(".")[0])
        return p, []
    return build


def parquet_case(mutate: Callable[[bytes, random.Random], bytes]) -> Callable:
    def build(d: Path, rng: random.Random):
        p = d / "circuit.parquet"
        p.write_bytes(mutate((SAMPLES / "circuit.parquet").read_bytes(), rng))
        shutil.copy(SAMPLES / "circuit.meta.toml", d / "circuit.meta.toml")
        return p, []
    return build


def parquet_frame_case(mutate: Callable[[pd.DataFrame, random.Random], pd.DataFrame]):
    def build(d: Path, rng: random.Random):
        df = mutate(pd.read_parquet(SAMPLES / "circuit.parquet"), rng)
        p = d / "circuit.parquet"
        df.to_parquet(p)
        shutil.copy(SAMPLES / "circuit.meta.toml", d / "circuit.meta.toml")
        return p, []
    return build


def sidecar_case(text_fn: Callable[[str], str]) -> Callable:
    def build(d: Path, rng: random.Random):
        shutil.copy(SAMPLES / "handmade.csv", d / "log.csv")
        (d / "log.meta.toml").write_text(text_fn((SAMPLES / "handmade.meta.toml").read_text()))
        return d / "log.csv", []
    return build


def mapping_case(text_fn: Callable[[str], str]) -> Callable:
    def build(d: Path, rng: random.Random):
        for f in ("foreign.csv", "foreign.meta.toml"):
            shutil.copy(SAMPLES / f, d / f)
        (d / "map.toml").write_text(text_fn((SAMPLES / "foreign.mapping.toml").read_text()))
        return d / "foreign.csv", ["--mapping", d / "map.toml"]
    return build


# ------------------------------------------------------------------ content mutations


def swap_pairs(k):
    def f(df, rng):
        for i in rng.sample(range(10, len(df) - 10), k):
            df.iloc[[i, i + 1]] = df.iloc[[i + 1, i]].to_numpy()
        return df
    return f


def repeat_rows(k):
    def f(df, rng):
        idx = sorted(rng.sample(range(len(df)), k))
        return pd.concat([df, df.iloc[idx]]).sort_index(kind="stable").reset_index(drop=True)
    return f


def conflict_dup(df, rng):
    i = rng.randrange(10, len(df) - 10)
    extra = df.iloc[[i]].copy()
    extra["n_norm_g"] += 0.1
    return pd.concat([df.iloc[:i + 1], extra, df.iloc[i + 1:]]).reset_index(drop=True)


def reset_clock(df, rng):
    i = rng.randrange(100, len(df) - 100)
    df.loc[i:, "t_s"] -= rng.choice([30.0, 100.0, df.loc[i, "t_s"]])
    return df


def jump_clock(df, rng):
    i = rng.randrange(900, len(df) - 100)
    df.loc[i:, "t_s"] += rng.choice([600.0, 3600.0, 86400.0])
    return df


def gap(df, rng):
    i = rng.randrange(100, len(df) - 400)
    return df.drop(index=range(i, i + rng.randrange(20, 300))).reset_index(drop=True)


def scale(col, factor):
    def f(df, rng):
        cols = col if isinstance(col, tuple) else (col,)
        for c in cols:
            df[c] = df[c] * factor
        return df
    return f


def radians(df, rng):
    for c in ("roll_deg", "pitch_deg", "heading_deg"):
        df[c] = np.radians(df[c])
    return df


def put(col, values):
    def f(df, rng):
        rows = df.index[df[col].notna()].to_list()
        for v in values:
            df.loc[rng.choice(rows[10:-10]), col] = v
        return df
    return f


def nan_cells(k):
    def f(df, rng):
        for _ in range(k):
            c = rng.choice([c for c in df.columns if c != "t_s"])
            df.loc[rng.randrange(len(df)), c] = np.nan
        return df
    return f


def text_cell(df, rng):
    df = df.astype({"tas_mps": object})
    df.loc[rng.randrange(len(df)), "tas_mps"] = rng.choice(["fast", "1,5", "--", "0x10"])
    return df


def truncate(n):
    def f(df, rng):
        start = rng.randrange(0, len(df) - n) if n < len(df) else 0
        return df.iloc[start:start + n].reset_index(drop=True)
    return f


def drop_col(col):
    return lambda df, rng: df.drop(columns=[col])


def rename_col(col, new):
    return lambda df, rng: df.rename(columns={col: new})


def negate(col):
    def f(df, rng):
        df[col] = -df[col]
        return df
    return f


def freeze(col):
    def f(df, rng):
        df[col] = np.where(df[col].notna(), df[col].dropna().iloc[0], np.nan)
        return df
    return f


def shuffle_cols(df, rng):
    cols = list(df.columns)
    rng.shuffle(cols)
    return df[cols]


def shuffle_rows(df, rng):
    return df.sample(frac=1.0, random_state=rng.randrange(1 << 30)).reset_index(drop=True)


# ------------------------------------------------------------------ byte / encoding mutations


def t_empty(text, rng):
    return b""


def t_header_only(text, rng):
    return text.splitlines()[0] + "\n"


def t_binary(text, rng):
    return bytes(rng.randrange(256) for _ in range(4096))


def t_truncate_bytes(text, rng):
    b = text.encode()
    return b[: rng.randrange(50, len(b) - 1)]


def t_flip_bytes(k):
    def f(text, rng):
        b = bytearray(text.encode())
        for _ in range(k):
            b[rng.randrange(len(b))] = rng.randrange(256)
        return bytes(b)
    return f


def t_utf16(text, rng):
    return text.encode("utf-16")


def t_cp1252(text, rng):
    lines = text.splitlines()
    lines[0] = lines[0].replace("sat_degc", "sat_°c")
    return "\n".join(lines).encode("cp1252")


def t_bom(text, rng):
    return b"\xef\xbb\xbf" + text.encode()


def t_crlf(text, rng):
    return text.replace("\n", "\r\n")


def t_delim(sep):
    return lambda text, rng: text.replace(",", sep)


def t_nul(text, rng):
    i = rng.randrange(100, len(text))
    return text[:i] + "\x00" + text[i:]


def t_wrong_fields(text, rng):
    lines = text.splitlines()
    i = rng.randrange(2, len(lines))
    lines[i] = lines[i] + ",1,2"
    return "\n".join(lines) + "\n"


def t_blank_lines(text, rng):
    lines = text.splitlines()
    for _ in range(3):
        lines.insert(rng.randrange(2, len(lines)), "")
    return "\n".join(lines) + "\n"


def t_no_final_newline_cut(text, rng):
    return text.rstrip("\n")[:-3]


def b_truncate(b, rng):
    return b[: rng.randrange(8, len(b) - 8)]


def b_flip(b, rng):
    a = bytearray(b)
    for _ in range(8):
        a[rng.randrange(len(a))] = rng.randrange(256)
    return bytes(a)


# ------------------------------------------------------------------ output arguments


def o_over_log(d, log):
    return ["-o", log]


def o_summary_over_sidecar(d, log):
    return ["-o", d / "out.parquet", "--summary", log.with_name(log.name.split(".")[0]
                                                                 + ".meta.toml")]


def o_same(d, log):
    return ["-o", d / "out.parquet", "--summary", d / "out.parquet"]


def o_missing_folder(d, log):
    return ["-o", d / "nowhere" / "out.parquet"]


def o_empty(d, log):
    return ["-o", ""]


def o_bad_suffix(d, log):
    return ["-o", d / "out.txt"]


def o_report_over_log(d, log):
    return ["-o", d / "out.parquet", "--report", log]


def o_existing_folder(d, log):
    (d / "afolder").mkdir()
    return ["-o", d / "afolder"]


def o_store_over_sidecar(d, log):
    return ["-o", d / "out.parquet", "--store", log.with_name(log.name.split(".")[0]
                                                              + ".meta.toml")]


def o_report_folder_with_input(d, log):
    shutil.copy(log, d / "wind.png")
    return ["-o", d / "out.parquet", "--report", d, "--gnss", d / "wind.png"]


def o_csv(d, log):
    return ["-o", d / "out.csv"]


def o_geojson(d, log):
    return ["-o", d / "out.geojson"]


def o_report(d, log):
    return ["-o", d / "out.parquet", "--report", d / "rep"]


# ------------------------------------------------------------------ the case list


def _content() -> list[tuple[str, Callable, set[str]]]:
    out = []
    for k in (1, 3, 6):
        out.append((f"swap-{k}", frame_case(swap_pairs(k)), {"repairable"}))
    for k in (1, 5):
        out.append((f"repeat-{k}", frame_case(repeat_rows(k)), {"repairable"}))
    out += [
        ("conflicting-duplicate", frame_case(conflict_dup), set()),
        ("clock-reset", frame_case(reset_clock), set()),
        ("clock-jump", frame_case(jump_clock), set()),
        ("recording-gap", frame_case(gap), set()),
        ("attitude-radians", frame_case(radians), set()),
        ("time-ms", frame_case(scale("t_s", 1000.0)), set()),
        ("time-minutes", frame_case(scale("t_s", 1 / 60.0)), set()),
        ("gnss-alt-ft", frame_case(scale("gnss_alt_m", 1 / 0.3048)), set()),
        ("baro-ft", frame_case(scale("baro_alt_m", 1 / 0.3048)), set()),
        ("tas-kt", frame_case(scale("tas_mps", 1.943844)), set()),
        ("loads-mps2", frame_case(scale(("n_long_g", "n_lat_g", "n_norm_g"), 9.80665)), set()),
        ("spike-30g", frame_case(put("n_norm_g", [30.0])), set()),
        ("two-1e308", frame_case(put("tas_mps", [1e308, 1e308])), set()),
        ("inf", frame_case(put("baro_alt_m", [np.inf])), set()),
        ("nan-few", frame_case(nan_cells(5)), set()),
        ("nan-many", frame_case(nan_cells(400)), set()),
        ("text-cell", frame_case(text_cell), set()),
        ("negate-n-norm", frame_case(negate("n_norm_g")), set()),
        ("negate-n-long", frame_case(negate("n_long_g")), set()),
        ("negate-roll", frame_case(negate("roll_deg")), set()),
        ("freeze-heading", frame_case(freeze("heading_deg")), set()),
        ("drop-tas", frame_case(drop_col("tas_mps")), set()),
        ("drop-gnss-lat", frame_case(drop_col("gnss_lat_deg")), set()),
        ("drop-time", frame_case(drop_col("t_s")), set()),
        ("rename-roll", frame_case(rename_col("roll_deg", "rol_deg")), set()),
        ("shuffle-columns", frame_case(shuffle_cols), set()),
        ("shuffle-rows", frame_case(shuffle_rows), set()),
        ("no-sidecar", frame_case(lambda df, rng: df, meta=False), set()),
    ]
    for n in (1, 2, 10, 60, 400):
        out.append((f"truncate-{n}", frame_case(truncate(n)), set()))
    return out


def _encoding() -> list[tuple[str, Callable, set[str]]]:
    return [
        ("empty-file", text_case(t_empty), set()),
        ("header-only", text_case(t_header_only), set()),
        ("binary", text_case(t_binary), set()),
        ("truncated-bytes", text_case(t_truncate_bytes), set()),
        ("flip-2-bytes", text_case(t_flip_bytes(2)), set()),
        ("flip-20-bytes", text_case(t_flip_bytes(20)), set()),
        ("utf16", text_case(t_utf16), set()),
        ("cp1252-header", text_case(t_cp1252), set()),
        ("bom", text_case(t_bom), set()),
        ("crlf", text_case(t_crlf), set()),
        ("semicolon", text_case(t_delim(";")), set()),
        ("tab", text_case(t_delim("\t")), set()),
        ("nul-byte", text_case(t_nul), set()),
        ("wrong-field-count", text_case(t_wrong_fields), set()),
        ("blank-lines", text_case(t_blank_lines), set()),
        ("cut-last-row", text_case(t_no_final_newline_cut), set()),
        ("parquet-named-csv", text_case(
            lambda t, r: (SAMPLES / "circuit.parquet").read_bytes(), name="pq.csv"), set()),
        ("parquet-truncated", parquet_case(b_truncate), set()),
        ("parquet-flipped", parquet_case(b_flip), set()),
        ("parquet-time-ms", parquet_frame_case(scale("t_s", 1000.0)), set()),
        ("parquet-swap", parquet_frame_case(swap_pairs(3)), {"repairable"}),
        ("parquet-radians", parquet_frame_case(radians), set()),
    ]


def _metadata() -> list[tuple[str, Callable, set[str]]]:
    return [
        ("sidecar-garbage", sidecar_case(lambda t: "this is [not toml"), set()),
        ("sidecar-empty", sidecar_case(lambda t: ""), set()),
        ("sidecar-bad-lat", sidecar_case(lambda t: t.replace("lat_deg = 40.46",
                                                             "lat_deg = 940.46")), set()),
        ("sidecar-unknown-key", sidecar_case(lambda t: t + "\n[flight2]\nx = 1\n"), set()),
        ("sidecar-escape", sidecar_case(lambda t: t + '\n[files]\ngnss = "../../etc/passwd"\n'),
         set()),
        ("sidecar-missing-companion", sidecar_case(lambda t: t + '\n[files]\ngnss = "g.csv"\n'),
         set()),
        ("sidecar-bad-epoch", sidecar_case(lambda t: t.replace("2026-03-15T09:00:00Z",
                                                               "yesterday")), set()),
        ("sidecar-binary", sidecar_case(lambda t: "\x00\x01\x02"), set()),
        ("mapping-garbage", mapping_case(lambda t: "[[[["), set()),
        ("mapping-wrong-unit", mapping_case(lambda t: t.replace('unit = "ft"', 'unit = "kt"', 1)),
         set()),
        ("mapping-ft-as-m", mapping_case(
            lambda t: t.replace('column = "ALT_FT"\nunit = "ft"', 'column = "ALT_FT"\nunit = "m"')),
         set()),
        ("mapping-missing-column", mapping_case(lambda t: t.replace('"VRTG"', '"VRTG2"')), set()),
        ("mapping-ok", mapping_case(lambda t: t), set()),
    ]


OUTPUTS = [o_over_log, o_summary_over_sidecar, o_same, o_missing_folder, o_empty, o_bad_suffix,
           o_report_over_log, o_existing_folder, o_store_over_sidecar,
           o_report_folder_with_input, o_csv, o_geojson, o_report]


def build_cases(seed: int) -> list[Case]:
    rng = random.Random(seed)
    cases: list[Case] = []
    groups = {"content": _content(), "encoding": _encoding(), "metadata": _metadata()}
    commands = ("info", "clean", "reconstruct")
    for group, items in groups.items():
        for name, build, tags in items:
            # every mutation through reconstruct, and through info or clean (alternating)
            for cmd in ("reconstruct", commands[rng.randrange(2)]):
                cases.append(Case(f"{group}-{name}-{cmd}", cmd, build, rng.randrange(1 << 30),
                                  tags=tags))
    base = frame_case(lambda df, rng: df)
    for o in OUTPUTS:
        cases.append(Case(f"outputs-{o.__name__[2:]}-reconstruct", "reconstruct", base,
                          rng.randrange(1 << 30), out_args=o))
    for o in (o_over_log, o_summary_over_sidecar, o_empty, o_bad_suffix, o_missing_folder):
        if o is o_summary_over_sidecar:
            continue
        cases.append(Case(f"outputs-{o.__name__[2:]}-clean", "clean", base,
                          rng.randrange(1 << 30), out_args=o))
    return cases


# ------------------------------------------------------------------ issue #39, third round
# Faults the mutation fuzzer found against main, each with the exit code it must give and the
# words its message must hold.  Appended after the seeded list, so that list is unchanged.


def nested_columns(df: pd.DataFrame, rng: random.Random) -> pd.DataFrame:
    """An extra struct column and an extra list column (pyarrow writes dicts and lists so)."""
    n = len(df)
    return df.assign(extra_struct=[{"a": i, "b": "x"} for i in range(n)],
                     extra_list=[[1.0, float(i)] for i in range(n)])


def o_store_read_only(d, log):
    """A store the user cannot write (file mode 0444; as root os.access is patched, below)."""
    from flightrecon.store.db import connect

    con, _, _ = connect(d / "ro.sqlite")   # an empty store of this version
    con.close()
    (d / "ro.sqlite").chmod(0o444)
    return ["-o", d / "out.parquet", "--store", d / "ro.sqlite"]


def env_store_read_only(d: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real = os.access

    def access(p, mode, *a, **k):
        if Path(p).name == "ro.sqlite" and mode & os.W_OK:
            return False
        return real(p, mode, *a, **k)

    monkeypatch.setattr(os, "access", access)


def o_store_not_sqlite(d, log):
    (d / "notes.sqlite").write_text("not a database\n")
    return ["-o", d / "out.parquet", "--store", d / "notes.sqlite"]


def o_store_missing_folder(d, log):
    return ["-o", d / "out.parquet", "--store", d / "nowhere" / "s.sqlite"]


def o_store_folder_read_only(d, log):
    (d / "rodir").mkdir()
    return ["-o", d / "out.parquet", "--store", d / "rodir" / "s.sqlite"]


def env_folder_read_only(d: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real = os.access

    def access(p, mode, *a, **k):
        if Path(p).name == "rodir" and mode & os.W_OK:
            return False
        return real(p, mode, *a, **k)

    monkeypatch.setattr(os, "access", access)


def o_result_folder_read_only(d, log):
    (d / "rodir").mkdir()
    return ["-o", d / "rodir" / "out.parquet"]


def o_summary_folder_read_only(d, log):
    (d / "rodir").mkdir()
    return ["-o", d / "out.parquet", "--summary", d / "rodir" / "s.json"]


def o_report_folder_read_only(d, log):
    (d / "rodir").mkdir()
    return ["-o", d / "out.parquet", "--report", d / "rodir"]


def _round_three(rng: random.Random) -> list[Case]:
    sub = "[channels.n_norm_g]\ncolumn = \"VRTG\"\nunit = \"g\"\nsign = 1"
    mapping = [
        ("mapping-key-typo", lambda t: t.replace(sub, sub.replace("sign = 1", "sgin = 1")),
         (6, ("map.toml", "line 9", "[channels.n_norm_g]", "'sgin'", "did you mean 'sign'"))),
        ("mapping-offset-typo", lambda t: t.replace(sub, sub + "\nofset = 0.0"),
         (6, ("map.toml", "[channels.n_norm_g]", "'ofset'", "did you mean 'offset'"))),
        ("mapping-table-typo", lambda t: t.replace("[channels.n_lat_g]", "[chanels.n_lat_g]"),
         (6, ("map.toml", "'chanels'", "did you mean 'channels'"))),
        ("mapping-derived-without-source", lambda t: t.replace('from = "ias"', 'from = "cas"'),
         (6, ("map.toml", "[channels.tas_mps] from", "cas_mps", "foreign.csv",
              "did you mean from = 'ias'"))),
        ("mapping-derived-source-unmapped",
         lambda t: t.replace('[channels.ias_mps]\ncolumn = "IAS_KT"\nunit = "kt"\n', ""),
         (6, ("map.toml", "[channels.tas_mps] from", "ias_mps"))),
        ("mapping-time-column-as-channel",
         lambda t: t.replace('column = "VRTG"', 'column = "TIME"'),
         (6, ("map.toml", "[channels.n_norm_g]", "TIME"))),
        ("mapping-channel-of-another-group",
         lambda t: t + '\n[gnss.channels.n_norm_g]\ncolumn = "NZ"\n',
         (6, ("map.toml", "[gnss.channels.n_norm_g]", "not a gnss channel"))),
    ]
    cases = []
    for name, fn, expect in mapping:
        for cmd in ("info", "reconstruct"):
            cases.append(Case(f"round3-{name}-{cmd}", cmd, mapping_case(fn),
                              rng.randrange(1 << 30), expect=expect))
    for cmd in ("info", "reconstruct"):
        cases.append(Case(f"round3-parquet-nested-columns-{cmd}", cmd,
                          parquet_frame_case(nested_columns), rng.randrange(1 << 30),
                          expect=(0, ())))
    base = frame_case(lambda df, rng: df)
    for o, env, expect in (
            (o_store_read_only, env_store_read_only, (10, ("ro.sqlite", "read-only"))),
            (o_store_not_sqlite, None, (10, ("notes.sqlite", "not a SQLite"))),
            (o_store_missing_folder, None, (10, ("s.sqlite", "nowhere", "does not exist"))),
            (o_store_folder_read_only, env_folder_read_only,
             (10, ("s.sqlite", "rodir", "not writable"))),
            (o_result_folder_read_only, env_folder_read_only,
             (9, ("out.parquet", "rodir", "not writable"))),
            (o_summary_folder_read_only, env_folder_read_only,
             (9, ("s.json", "rodir", "not writable"))),
            (o_report_folder_read_only, env_folder_read_only, (9, ("rodir", "cannot be written")))):
        cases.append(Case(f"round3-outputs-{o.__name__[2:]}-reconstruct", "reconstruct", base,
                          rng.randrange(1 << 30), out_args=o, expect=expect, env=env))
    return cases


CASES = build_cases(SEED)
CASES += _round_three(random.Random(SEED + 39))


# ------------------------------------------------------------------ the checks


def _digest(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _leftovers(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if TMP_TAG in p.name]


def _physically_possible(track: pd.DataFrame) -> None:
    t = track["t_s"].to_numpy(float)
    assert np.all(np.isfinite(t)) and np.all(np.diff(t) > 0), "time not increasing"
    n, e = track["north_m"].to_numpy(float), track["east_m"].to_numpy(float)
    ok = np.isfinite(n) & np.isfinite(e)
    assert ok.mean() >= 0.5, f"only {ok.mean():.0%} of the positions are finite"
    i = np.flatnonzero(ok)
    v = np.hypot(np.diff(n[i]), np.diff(e[i])) / np.diff(t[i])
    assert np.nanmax(v) < 400.0, f"speed {np.nanmax(v):.0f} m/s between samples"
    if "up_m" in track.columns:
        up = track["up_m"].to_numpy(float)
        upf = up[np.isfinite(up)]
        assert upf.size and upf.min() > -1000 and upf.max() < 20000, "height impossible"


def _check_outputs(case: Case, d: Path, args: list) -> None:
    if case.command == "reconstruct":
        out = None
        if "-o" in args:
            out = Path(args[args.index("-o") + 1])
        else:
            log = Path(args[1])
            out = log.with_name(log.name.split(".")[0] + ".recon.parquet")
        if out.suffix == ".parquet":
            track = pd.read_parquet(out)
        elif out.suffix == ".csv":
            track = pd.read_csv(out)
        else:
            assert out.stat().st_size > 0
            return
        _physically_possible(track)
        summ = out.with_name(out.stem + ".summary.json")
        if "--summary" in args:
            summ = Path(args[args.index("--summary") + 1])
        doc = json.loads(summ.read_text())
        assert any(m.get("status") == "ok" for m in doc["methods"].values())
    elif case.command == "clean":
        out = Path(args[args.index("-o") + 1])
        grid = pd.read_parquet(out) if out.suffix == ".parquet" else pd.read_csv(out)
        t = grid["t_s"].to_numpy(float)
        assert len(t) > 1 and np.all(np.diff(t) > 0)


def _names_a_file(err: str, d: Path, args: list) -> bool:
    names = {p.name for p in d.rglob("*")} | {d.name}
    names |= {Path(str(a)).name for a in args if str(a)}
    names.discard("")
    return any(n in err for n in names)


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_fuzz_case(case: Case, tmp_path, capsys, monkeypatch):
    d = tmp_path / "case"
    d.mkdir()
    log, extra = case.build(d, random.Random(case.seed))
    if case.out_args is not None:
        outs = case.out_args(d, log)
    elif case.command == "clean":
        outs = ["-o", d / "clean.parquet"]
    elif case.command == "reconstruct":
        outs = ["-o", d / "out.parquet"]
    else:
        outs = []
    args = [case.command, log, *extra, *outs]
    before = _digest(d)
    if case.env is not None:
        case.env(d, monkeypatch)
    capsys.readouterr()
    try:
        main(["--quiet", *[str(a) for a in args]])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0) if not isinstance(exc.code, str) else 1
    cap = capsys.readouterr()
    err = cap.err
    assert code in DOCUMENTED and code != 1, f"exit {code}: {err[-2000:]}"
    assert "Traceback" not in err and "internal error" not in err, err[-2000:]
    if 3 <= code <= 10:
        assert _names_a_file(err, d, args), f"exit {code}, no file named: {err}"
    after = _digest(d)
    changed = [k for k, h in before.items() if after.get(k) != h]
    assert not changed, f"inputs modified or removed: {changed}"
    assert not _leftovers(tmp_path), _leftovers(tmp_path)
    if code == 0:
        _check_outputs(case, d, args)
    if "repairable" in case.tags and case.command != "info":
        assert code == 0, f"a repairable log was refused: {err}"
    if case.expect is not None:
        want, words = case.expect
        assert code == want, f"exit {code}, expected {want}: {err[-2000:]}"
        missing = [w for w in words if w not in err]
        assert not missing, f"the message lacks {missing}: {err}"


# ------------------------------------------------------------------ signals


SIGNAL_CASES = [(s, t) for s in ("SIGINT", "SIGTERM") for t in (1.0, 2.5, 4.0)]


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("signame,delay_s", SIGNAL_CASES,
                         ids=[f"{s}-{t}s" for s, t in SIGNAL_CASES])
def test_fuzz_signal(tmp_path, signame, delay_s):
    d = tmp_path / "case"
    d.mkdir()
    log, _ = frame_case(swap_pairs(2))(d, random.Random(delay_s))
    before = _digest(d)
    sig = getattr(signal, signame)
    cmd = [sys.executable, "-m", "flightrecon", "--quiet", "reconstruct", str(log),
           "-o", str(d / "out.parquet"), "--report", str(d / "rep")]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    time.sleep(delay_s)
    p.send_signal(sig)
    _, err = p.communicate(timeout=600)
    err = err.decode()
    assert p.returncode in (0, 128 + sig, -sig), err
    assert "Traceback" not in err
    after = _digest(d)
    assert all(after.get(k) == h for k, h in before.items())
    assert not _leftovers(tmp_path)
    outs = {k for k in after if k not in before}
    if p.returncode == 0:
        _physically_possible(pd.read_parquet(d / "out.parquet"))
    else:     # all or nothing: result, summary and report together or none of them
        assert outs in (set(), {"out.parquet", "out.summary.json"} | {
            k for k in after if k.startswith("rep/")}), outs
        assert not [k for k in outs if k.startswith("rep/")] or "out.parquet" in outs


def test_fuzz_list_size():
    """At least 150 cases in CI (issue #24 acceptance)."""
    assert len(CASES) + len(SIGNAL_CASES) >= 150
