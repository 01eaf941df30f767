"""``flightrecon coeffs``: commands, output, and exit code 10 on a bad store."""

import csv
import hashlib
import json
import math
import sqlite3

import pytest
from click.testing import CliRunner

from flightrecon.cli import coeffs
from flightrecon.cli.main import main
from flightrecon.store import CSV_COLUMNS, CoefficientStore, FlightCoefficients

N, P = "negative", "positive"


def fit(flight, k1, branch=(N, N, N), converged=True, aircraft="4K-AZ01", day=1):
    return FlightCoefficients(
        aircraft_id=aircraft, flight_id=flight, flight_date_utc=f"2024-05-{day:02d}T10:00:00Z",
        duration_s=3600.0, k1=k1, k2=-1e-4, k3=-0.02, branch=branch, converged=converged,
        residual_m=3.5 if converged else math.nan, iterations=6, software_version="0.1.0",
        settings={"rate_hz": 16}, input_hashes={"log": "cafe"})


@pytest.fixture
def store_path(tmp_path):
    path = tmp_path / "s.sqlite"
    with CoefficientStore(path) as store:
        store.record_many([fit("F1", -0.010, day=1), fit("F2", -0.012, day=3),
                           fit("F3", -0.014, day=5), fit("F4", 0.02, (P, N, N), day=6),
                           fit("F5", -0.5, converged=False, day=7),
                           fit("G1", -0.03, aircraft="9H-XYZ", day=2)])
    return path


def run(args, capsys):
    """Run the real entry point; return (exit code, stdout, stderr)."""
    with pytest.raises(SystemExit) as ei:
        main(args)
    out, err = capsys.readouterr()
    return ei.value.code, out, err


def test_list_and_show(store_path, capsys):
    code, out, _ = run(["coeffs", "list", "--store", str(store_path)], capsys)
    assert code == 0 and "6 flight(s), 2 aircraft" in out and "G1" in out
    code, out, _ = run(["coeffs", "list", "--aircraft", "9H-XYZ", "--json",
                        "--store", str(store_path)], capsys)
    rows = json.loads(out)
    assert code == 0 and [r["flight_id"] for r in rows] == ["G1"]
    code, out, _ = run(["coeffs", "show", "4K-AZ01", "F5", "--json", "--store", str(store_path)],
                       capsys)
    d = json.loads(out)
    assert code == 0 and d["residual_m"] is None and d["converged"] is False
    code, out, _ = run(["coeffs", "show", "4K-AZ01", "F2", "--store", str(store_path)], capsys)
    assert code == 0 and "-0.012" in out and '"rate_hz": 16' in out
    code, out, _ = run(["coeffs", "show", "4K-AZ01", "--store", str(store_path)], capsys)
    assert code == 0 and "5 Sabziev fit(s) of 4K-AZ01" in out
    code, _, err = run(["coeffs", "show", "NOPE", "--store", str(store_path)], capsys)
    assert code == 10 and "no flights of aircraft 'NOPE'" in err


def test_average(store_path, capsys):
    code, out, _ = run(["coeffs", "average", "4K-AZ01", "--json", "--store", str(store_path)],
                       capsys)
    d = json.loads(out)
    k1 = d["axes"][0]
    # converged negative-branch k1: F1, F2, F3 -> mean -0.012, sample std 0.002 (by hand)
    assert code == 0 and k1["n"] == 3 and k1["branch"] == N
    assert k1["mean"] == pytest.approx(-0.012, rel=1e-12)   # 3 additions: rounding only
    assert k1["std"] == pytest.approx(0.002, rel=1e-12)
    assert k1["excluded_counts"] == {"not converged": 1, "branch positive, majority negative": 1}
    code, out, _ = run(["coeffs", "average", "4K-AZ01", "--store", str(store_path)], capsys)
    assert code == 0 and "excluded k1 of flight F4: branch positive" in out


def test_export_csv(store_path, tmp_path, capsys):
    out_csv = tmp_path / "k.csv"
    code, out, _ = run(["coeffs", "export", "-o", str(out_csv), "--aircraft", "4K-AZ01",
                        "--store", str(store_path)], capsys)
    assert code == 0 and "5 flight(s)" in out
    with open(out_csv, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0]) == CSV_COLUMNS and len(rows) == 5
    assert float(rows[1]["k1"]) == -0.012 and rows[4]["residual_m"] == ""  # repr round-trips
    assert json.loads(rows[0]["settings_json"]) == {"rate_hz": 16}
    code, _, err = run(["coeffs", "export", "-o", str(store_path), "--store", str(store_path)],
                       capsys)
    assert code == 9 and "overwrite" in err      # never over the store itself


def test_remove(store_path, capsys):
    runner = CliRunner()
    res = runner.invoke(coeffs.command, ["remove", "4K-AZ01", "--store", str(store_path)],
                        input="n\n")
    assert res.exit_code == 0 and "nothing removed" in res.output
    code, out, _ = run(["coeffs", "remove", "4K-AZ01", "F1", "--yes", "--store", str(store_path)],
                       capsys)
    assert code == 0 and "removed 1" in out
    code, _, err = run(["coeffs", "remove", "4K-AZ01", "F1", "--yes", "--store", str(store_path)],
                       capsys)
    assert code == 10 and "no flight 'F1'" in err
    res = runner.invoke(coeffs.command, ["remove", "4K-AZ01", "--store", str(store_path)],
                        input="y\n")
    assert res.exit_code == 0 and "removed 4" in res.output
    with CoefficientStore(store_path) as store:
        assert store.aircraft() == [("9H-XYZ", 1)]


def test_missing_store(tmp_path, capsys):
    path = tmp_path / "none.sqlite"
    code, out, _ = run(["coeffs", "list", "--store", str(path)], capsys)
    assert code == 0 and "does not exist yet" in out
    code, _, err = run(["coeffs", "average", "A", "--store", str(path)], capsys)
    assert code == 10 and "no coefficient store" in err
    assert not path.exists()                    # reading commands never create a store


@pytest.mark.parametrize("kind", ["random", "foreign"])
@pytest.mark.parametrize("sub", [["list"], ["show", "A"], ["average", "A"],
                                 ["remove", "A", "--yes"], ["export", "-o", "OUT"]])
def test_bad_store_exit_10_and_untouched(tmp_path, capsys, kind, sub):
    path = tmp_path / "bad.sqlite"
    if kind == "random":
        path.write_bytes(bytes((i * 37 + 11) % 256 for i in range(3000)))
    else:
        con = sqlite3.connect(path)
        con.execute("CREATE TABLE notes (id INTEGER PRIMARY KEY, body TEXT)")
        con.commit()
        con.close()
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    args = ["coeffs", *[str(tmp_path / "out.csv") if a == "OUT" else a for a in sub],
            "--store", str(path)]
    code, out, err = run(args, capsys)
    assert code == 10 and err.startswith("error: ") and "not a flightrecon coefficient store" in err
    assert "Traceback" not in err
    assert hashlib.sha256(path.read_bytes()).hexdigest() == digest
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.sqlite"]
