"""Count what issue 20's acceptance asks of the package's structure.

* implementations of the Kalman prediction, the measurement updates and the RTS backward step
  (functions whose body computes them, found by the shape of their code, not by their names);
* package files above 500 lines;
* functions above 80 lines, or with more than 12 positional parameters, outside the compiled
  kernels (``@nb.njit`` functions are reported apart: their argument lists cross the compiled
  boundary).

Run: ``python scripts/count_structure.py [ROOT]`` (prints a table; exit 0; ``ROOT`` another
checkout to count, by default this one).  The counts are a
measurement for the issue's record, not a test.
"""

from __future__ import annotations

import ast
import copy
import re
import sys
from pathlib import Path

ROOT = Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else Path(__file__).resolve().parents[1]
PKG = ROOT / "flightrecon"

# Textual signatures of each computation: the shape of the code that computes it (a product, a
# difference, a gain), never the name of a function it calls, so that a kernel which calls the
# estimation core does not count as an implementation of its own, and a hand-written copy does.
PATTERNS = {
    "predict": [
        r"F\s*@\s*P\s*@\s*F\.T",                                    # numpy F P F^T
        r"mm_into\((\w+), (P\w*), (\w+)\)\s*\n\s*mmt_into\(\3, \1,",             # loop A P A^T
        r"vals\[i, c\] \* B\[cols\[i, c\], j\]",                       # sparse F (P F^T)
        r"FP\[i, j\] \+= F\[i, m\] \* P\[m, j\]",
    ],
    "update": [
        r"IKH\s*@\s*P",                                               # numpy Joseph
        r"\(1\.0 if i == j else 0\.0\) - \w+\[i, j\]",                 # loop I - K H
        r"K\s*=\s*PH\s*/\s*S|inv_s\s*=\s*1\.0\s*/\s*S",                  # scalar gain
        r"-=\s*\(?\w+\s*\*\s*PH\[",                                      # P -= PH PH^T / S
        r"mmt_into\(B, G\w*, \w+\)\s*#?.*\n\s*mm_into\(\w+, Sp",  # B G^T S^+ (correlated)
    ],
    "rts_step": [
        r"xs\[k\]\s*=\s*x\[k\]\s*\+\s*C\s*@",                            # numpy mean
        r"C @ \(Ps\[k \+ 1\] - Pp\[k \+ 1\]\)",                          # numpy covariance
        r"Ps\w*\[[^\]]*\] - P(p|k1)\w*\[",                               # P_s,next - P_p
        r"xs\w*\[k \+ 1, \w+\] - xp\[k \+ 1, \w+\]",                     # x_s,next - x_p
        r"state_minus_into\(\w+, xs_next, xp",
        r"boxminus\(xs\[k \+ 1, 0\]",
    ],
}


def _code_of(fn: ast.FunctionDef) -> str:
    """The function's code without comments and docstrings (``ast.unparse`` of a copy whose
    docstrings are dropped), so that a formula written in prose does not count as code."""
    tree = copy.deepcopy(fn)
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and body
                and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return ast.unparse(tree)


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
            body = _code_of(node)
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
    print("## implementations (functions computing each, and the modules they are in)")
    for kind, names in impl.items():
        mods = sorted({nm.split("::")[0] for nm in names})
        print(f"{kind}: {len(names)} in {len(mods)} module(s): {', '.join(mods)}")
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
