"""Count what issue 20's acceptance asks of the package's structure.

* implementations of the Kalman prediction, the measurement updates and the RTS backward step
  (functions whose body computes them, found by the shape of their code, not by their names);
* package files above 500 lines;
* functions above 80 lines, or with more than 12 positional parameters, outside the compiled
  kernels (``@nb.njit`` functions are reported apart: their argument lists cross the compiled
  boundary).

Run: ``python scripts/count_structure.py`` (prints a table; exit 0).  The counts are a
measurement for the issue's record, not a test.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "flightrecon"

# textual signatures of each computation (any one in a function's source marks it)
PATTERNS = {
    "predict": [r"F\s*@\s*P\s*@\s*F\.T", r"_predict_cov\(",
                r"FP\[i, j\] \+= F\[i, m\] \* P\[m, j\]", r"_mmt\(T55, Phi|Phi P Phi"],
    "update": [r"IKH\s*@\s*P", r"K\s*=\s*PH\s*/\s*S|inv_s\s*=\s*1\.0\s*/\s*S",
               r"= \(1\.0 if i == j else 0\.0\) - K"],
    "rts_step": [r"xs\[k\]\s*=\s*x\[k\]\s*\+\s*C\s*@", r"x_s\[k\] = x_f\[k\] \+",
                 r"_chol_solve_rows\(Pp\[k \+ 1\]", r"cholesky_solve_columns\(L, A, GT\)",
                 r"_cholesky_solve\(Pk1, d"],
}


def _is_njit(fn: ast.FunctionDef) -> bool:
    return any("njit" in ast.unparse(d) for d in fn.decorator_list)


def main() -> int:
    big_files, long_fns, wide_fns, wide_kernels = [], [], [], []
    impl: dict[str, list[str]] = {k: [] for k in PATTERNS}
    for f in sorted(PKG.rglob("*.py")):
        src = f.read_text(encoding="utf-8")
        rel = f.relative_to(ROOT).as_posix()
        n_lines = src.count("\n") + 1
        if n_lines > 500:
            big_files.append((rel, n_lines))
        for node in ast.walk(ast.parse(src)):
            if not isinstance(node, ast.FunctionDef):
                continue
            body = ast.get_source_segment(src, node) or ""
            length = node.end_lineno - node.lineno + 1
            npos = len(node.args.posonlyargs) + len(node.args.args)
            name = f"{rel}::{node.name}"
            if _is_njit(node):
                if npos > 12:
                    wide_kernels.append((name, npos))
            else:
                if length > 80:
                    long_fns.append((name, length))
                if npos > 12:
                    wide_fns.append((name, npos))
            for kind, pats in PATTERNS.items():
                if any(re.search(p, body) for p in pats):
                    impl[kind].append(name)
    print("## implementations (functions computing each)")
    for kind, names in impl.items():
        print(f"{kind}: {len(names)}")
        for n in names:
            print(f"    {n}")
    print(f"\n## package files above 500 lines: {len(big_files)}")
    for rel, n in big_files:
        print(f"    {rel}: {n}")
    print(f"\n## functions above 80 lines (not compiled): {len(long_fns)}")
    for name, n in sorted(long_fns, key=lambda x: -x[1]):
        print(f"    {name}: {n}")
    print(f"\n## functions with more than 12 positional parameters (not compiled): {len(wide_fns)}")
    for name, n in wide_fns:
        print(f"    {name}: {n}")
    print(f"\n## compiled kernels with more than 12 positional parameters: {len(wide_kernels)}")
    for name, n in sorted(wide_kernels, key=lambda x: -x[1]):
        print(f"    {name}: {n}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
