"""The docs as a reference: every table names the command that regenerates it, and nothing in
the README or the docs points outside the repository (a public clone has no folder beside it).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from _scripts import load_script

ROOT = Path(__file__).resolve().parents[1]
TABLES = sorted((ROOT / "docs" / "tables").glob("*.md"))
REGENERATE = re.compile(r"^Regenerate: `python (scripts/[\w.]+\.py)( [^`]*)?`$")


@pytest.mark.parametrize("table", TABLES,
                         ids=lambda t: t.name)
def test_every_table_starts_with_the_command_that_writes_it(table: Path) -> None:
    """A table in docs/tables whose origin a reader cannot rerun is a snapshot: the first line
    names the script (which must exist) and its options."""
    first = table.read_text(encoding="utf-8").splitlines()[0]
    m = REGENERATE.match(first)
    assert m, f"{table.name}: first line {first!r}"
    assert (ROOT / m.group(1)).is_file(), f"{table.name}: {m.group(1)} does not exist"


def test_the_real_flights_table_names_its_command() -> None:
    """The table of docs/realflights.md (between its markers, written by the script) too."""
    text = (ROOT / "docs" / "realflights.md").read_text(encoding="utf-8")
    inside = text.split("<!-- table -->", 1)[1].split("<!-- /table -->", 1)[0]
    assert inside.strip().splitlines()[0] == (
        "Regenerate: `python scripts/realflight_study.py --data DIR/matlab`")


@pytest.mark.parametrize("page", [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))],
                         ids=lambda p: p.name)
def test_nothing_points_outside_the_repository(page: Path) -> None:
    """The maths, the conventions and the data a page relies on are in the repository: no
    reference to the former shared folder, its METHODS.md or a path above the checkout."""
    text = page.read_text(encoding="utf-8")
    for pattern in (r"METHODS\.md", r"\.\./shared", r"shared folder", r"\]\(\.\./\.\./"):
        hits = [line for line in text.splitlines() if re.search(pattern, line)]
        assert not hits, f"{page.name}: {pattern}: {hits[:3]}"


def test_a_script_writes_the_command_it_was_run_with() -> None:
    """The header line is the script run and its options as typed, quoted where needed."""
    th = load_script("table_header")
    assert th.command_line("scripts/mc_arms.py", ["--runs", "200"]) == (
        "python scripts/mc_arms.py --runs 200")
    assert th.header("/abs/scripts/mc_jsbsim.py", ["--before-label", "before (third)"]) == (
        "Regenerate: `python scripts/mc_jsbsim.py --before-label 'before (third)'`\n\n")
