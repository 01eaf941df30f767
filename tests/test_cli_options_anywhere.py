"""The options of the whole command line (--debug, --quiet, --verbose) are accepted where a
user types them: before the subcommand and after it, with the same meaning, for every
subcommand (issue 53: ``flightrecon reconstruct LOG --quiet`` was "No such option")."""

from __future__ import annotations

from pathlib import Path

import click
import pytest

from flightrecon.cli.main import CONSOLE_OPTIONS, cli, main

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
CIRCUIT = SAMPLES / "circuit.parquet"


def _commands(cmd: click.Command, path: list[str]):
    """Every (path, command) under ``cmd``: groups and their subcommands."""
    yield path, cmd
    if isinstance(cmd, click.Group):
        for name, sub in cmd.commands.items():
            yield from _commands(sub, [*path, name])


PATHS = [path for path, _ in _commands(cli, []) if path]
FLAGS = [flag for _, flags, _ in CONSOLE_OPTIONS for flag in flags]


def _code(args: list[str]) -> int:
    try:
        main(args)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


def test_every_command_is_covered():
    """The walk finds the commands the tool has (a new one is covered without editing)."""
    assert {"info", "clean", "simulate", "reconstruct", "plot", "export", "batch",
            "coeffs", "coeffs list", "coeffs show"} <= {" ".join(p) for p in PATHS}


@pytest.mark.parametrize("path", PATHS, ids=[" ".join(p) for p in PATHS])
@pytest.mark.parametrize("flag", FLAGS)
def test_accepted_before_and_after_every_subcommand(path, flag, capsys):
    """``flightrecon SUB... FLAG --help`` and ``flightrecon FLAG SUB... --help`` both parse
    (exit 0), and the subcommand's help lists the option."""
    assert _code([*path, flag, "--help"]) == 0
    assert flag in capsys.readouterr().out
    assert _code([flag, *path, "--help"]) == 0


def _dummy_args(cmd: click.Command, tmp_path: Path) -> list[str]:
    """Values for ``cmd``'s required parameters that parse (the command itself is replaced
    by a spy, so they are never used)."""
    args: list[str] = []
    for p in cmd.params:
        if not p.required:
            continue
        if isinstance(p.type, click.Choice):
            value = str(p.type.choices[0])
        elif isinstance(p.type, click.Path):
            value = str(tmp_path / f"{p.name}.parquet")
        else:
            value = "x"
        if isinstance(p, click.Option):
            args.append(p.opts[0])
        args.append(value)
    return args


@pytest.mark.parametrize("path", PATHS, ids=[" ".join(p) for p in PATHS])
def test_same_meaning_before_and_after(path, tmp_path, monkeypatch):
    """Each option given after the subcommand reaches the command exactly as given before
    it: the settings the command reads (``ctx.obj``) are the same either way, and nothing is
    set without the option.  After a group (``coeffs --quiet list``) the group's first
    subcommand runs."""
    cmd: click.Command = cli
    for name in path:
        assert isinstance(cmd, click.Group)
        cmd = cmd.commands[name]
    args: list[str] = []
    if isinstance(cmd, click.Group):
        first = next(iter(cmd.commands))
        cmd = cmd.commands[first]
        args.append(first)
    seen: list[dict] = []

    def spy(*args, **kwargs):
        seen.append(dict(click.get_current_context().obj))

    monkeypatch.setattr(cmd, "callback", spy)
    args += _dummy_args(cmd, tmp_path)
    names = [name for name, _, _ in CONSOLE_OPTIONS]
    assert _code([*path, *args]) == 0
    assert {k: seen[-1].get(k) for k in names} == {k: False for k in names}
    for name, flags, _ in CONSOLE_OPTIONS:
        for flag in flags:
            assert _code([flag, *path, *args]) == 0
            before = seen[-1]
            for placed in ([*path, flag, *args], [*path, *args, flag]):
                assert _code(placed) == 0
                after = seen[-1]
                assert before[name] is True and after[name] is True, placed
                assert {k: after.get(k) for k in names} == {k: before.get(k) for k in names}


def test_quiet_and_verbose_exclude_each_other(capsys):
    """Both at once is a usage error (exit 2), wherever each is written."""
    assert _code(["--quiet", "info", str(CIRCUIT), "--verbose"]) == 2
    assert "exclude each other" in capsys.readouterr().err
    assert _code(["info", str(CIRCUIT), "-q", "-v"]) == 2


def test_reconstruct_quiet_after_the_subcommand(tmp_path, capsys):
    """The issue's command: ``reconstruct LOG ... --quiet`` runs, writes the same files and
    prints what ``--quiet reconstruct`` prints (only the paths written); without it the
    methods' lines follow on stderr."""
    def run(args: list[str], out: Path) -> tuple[str, str]:
        assert _code(args) == 0
        assert out.is_file()
        cap = capsys.readouterr()
        return cap.out.replace(str(out.with_suffix("")), "OUT"), cap.err

    common = [str(CIRCUIT), "--methods", "joint"]
    a, b, c = (tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv")
    out_after, err_after = run(["reconstruct", *common, "-o", str(a), "--quiet"], a)
    out_before, err_before = run(["--quiet", "reconstruct", *common, "-o", str(b)], b)
    assert out_after == out_before == "wrote OUT.csv\nwrote OUT.summary.json\n"
    assert err_after == err_before == ""
    _, err_loud = run(["reconstruct", *common, "-o", str(c)], c)
    assert "joint    ok" in err_loud


def test_verbose_prints_each_stage(tmp_path, capsys):
    """``clean LOG --verbose`` prints one line per stage with the time elapsed, also when
    stderr is not a terminal (as under pytest), and a last line with the total."""
    assert _code(["clean", str(SAMPLES / "handmade.csv"), "-o", str(tmp_path / "g.parquet"),
                  "--verbose"]) == 0
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("clean: ")]
    assert [ln.split(" (t = ")[0] for ln in lines[:-1]] == [
        "clean: ingest", "clean: cleaning", "clean: write"]
    assert lines[-1].startswith("clean: done in ")
    times = [float(ln.split("(t = ")[1].split(" s)")[0]) for ln in lines[:-1]]
    assert times == sorted(times)


# ------------------------------------------------------------------ warnings on the console


@pytest.fixture()
def log_with_extra_column(tmp_path) -> Path:
    """The shipped circuit with one column the schema does not know: a warning on reading."""
    import shutil

    import pandas as pd

    d = pd.read_csv(SAMPLES / "circuit.csv")
    d["mystery"] = 1.0
    log = tmp_path / "extra.csv"
    d.to_csv(log, index=False)
    shutil.copy(SAMPLES / "circuit.meta.toml", tmp_path / "extra.meta.toml")
    return log


@pytest.mark.parametrize("cmd", ["clean", "reconstruct", "info"])
def test_every_command_prints_the_tools_warnings_one_way(cmd, log_with_extra_column, capsys):
    """The same warning, from ``clean`` (which printed Python's ``<file>.py:<line>:
    FlightReconWarning: ...`` and the source line), ``reconstruct`` and ``info``: one line
    ``  warning: <message>`` on stderr, nothing of Python's format."""
    log = log_with_extra_column
    out = {"clean": ["-o", str(log.with_name("g.parquet"))],
           "reconstruct": ["--methods", "joint", "-o", str(log.with_name("r.csv"))],
           "info": []}[cmd]
    assert _code([cmd, str(log), *out]) == 0
    err = capsys.readouterr().err.splitlines()
    want = f"  warning: {log}: 1 column(s) not in the schema and not mapped, ignored: mystery"
    assert err.count(want) == 1, err
    assert not [ln for ln in err if "FlightReconWarning" in ln or ".py:" in ln], err


@pytest.mark.parametrize("where", ["before", "after"])
def test_quiet_keeps_the_warnings_off_the_console_and_in_the_report(where, tmp_path,
                                                                    log_with_extra_column,
                                                                    capsys):
    """With --quiet (before or after the subcommand) ``clean`` prints only the paths written,
    as ``reconstruct`` does; its warnings are in <stem>.cleaning.json either way."""
    import json

    out = tmp_path / "q.parquet"
    args = ["clean", str(log_with_extra_column), "-o", str(out)]
    assert _code(["--quiet", *args] if where == "before" else [*args, "--quiet"]) == 0
    cap = capsys.readouterr()
    assert cap.err == ""
    assert cap.out.splitlines()[0] == f"wrote {out}"
    report = json.loads(out.with_name("q.cleaning.json").read_text())
    assert report["warnings"] == [f"{log_with_extra_column}: 1 column(s) not in the schema "
                                  "and not mapped, ignored: mystery"]


def test_other_warnings_keep_pythons_format(capsys):
    """A warning that is not the tool's own (a library's) goes to the display in force
    before (Python's, or whatever replaced it); the tool's own is a console line."""
    import warnings

    from flightrecon.cli.console import console_warnings
    from flightrecon.errors import FlightReconWarning

    shown: list[str] = []
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = lambda message, category, *a, **k: shown.append(
            f"{category.__name__}: {message}")
        with console_warnings():
            warnings.warn("ours", FlightReconWarning, stacklevel=1)
            warnings.warn("theirs", DeprecationWarning, stacklevel=1)
    assert capsys.readouterr().err == "  warning: ours\n"
    assert shown == ["DeprecationWarning: theirs"]
