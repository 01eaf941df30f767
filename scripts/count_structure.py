"""Count what issues 20 and 40 ask of the package's structure.

* the time loops of a forward filter (a loop over an ascending range whose body predicts and
  updates) and of a backward smoother (a loop over a descending range whose body takes an RTS
  step), found by the shape of the code;
* private names (a leading underscore) imported from another module of the package;
* import circles among the package's modules (module-level imports, those under
  ``TYPE_CHECKING`` included) and imports against the data's direction (the estimation core
  importing a method, the pipeline or the CLI; a method importing the pipeline or the CLI; the
  pipeline importing the CLI);
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


FORWARD_BODY = (re.compile(r"\bpredict\w*\("), re.compile(r"\b(\w*update\w*|gain_into)\("))
BACKWARD_BODY = re.compile(r"\b(rts_step|rts_mean_solve|smoothed_step)\(")


def _range_direction(node: ast.For) -> str | None:
    """'up' for ``range(N)`` / ``range(a, b)``, 'down' for ``range(a, b, -1)``, else None."""
    it = node.iter
    if not (isinstance(it, ast.Call) and isinstance(it.func, ast.Name) and it.func.id == "range"):
        return None
    if len(it.args) == 3:
        step = ast.unparse(it.args[2]).replace(" ", "")
        return "down" if step.startswith("-") else "up"
    return "up"


def _time_loops(fn: ast.FunctionDef) -> tuple[int, int]:
    """Forward-filter and backward-smoother loops directly in ``fn`` (module docstring)."""
    fwd = bwd = 0
    for node in ast.walk(fn):
        if not isinstance(node, ast.For):
            continue
        body = "\n".join(ast.unparse(b) for b in node.body)
        d = _range_direction(node)
        if d == "up" and all(p.search(body) for p in FORWARD_BODY):
            fwd += 1
        elif d == "down" and BACKWARD_BODY.search(body):
            bwd += 1
    return fwd, bwd


def _module_of(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(tree: ast.Module, modules: set[str]) -> list[tuple[str, list[str]]]:
    """Module-level imports (and those under ``if TYPE_CHECKING``) of package modules: the
    imported module and the names taken from it."""
    out = []
    body = list(tree.body)
    for node in list(body):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            body.extend(node.body)
    for node in body:
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if not node.module.startswith("flightrecon"):
                continue
            names = [a.name for a in node.names]
            subs = [n for n in names if f"{node.module}.{n}" in modules]
            for n in subs:
                out.append((f"{node.module}.{n}", []))
            rest = [n for n in names if n not in subs]
            if rest or not subs:
                out.append((node.module, rest))
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("flightrecon"):
                    out.append((a.name, []))
    return out


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


#: the data's direction: a module of a layer imports nothing of the layers after it
LAYERS = [("flightrecon.estimation", ("flightrecon.methods", "flightrecon.pipeline",
                                      "flightrecon.cli")),
          ("flightrecon.methods", ("flightrecon.pipeline", "flightrecon.cli")),
          ("flightrecon.pipeline", ("flightrecon.cli",))]


def _structure_report() -> None:
    files = sorted(PKG.rglob("*.py"))
    modules = {_module_of(f) for f in files}
    fwd_loops, bwd_loops, private, against = [], [], [], []
    graph: dict[str, set[str]] = {}
    for f in files:
        tree = ast.parse(f.read_text(encoding="utf-8"))
        mod = _module_of(f)
        rel = f.relative_to(ROOT).as_posix()
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef):
                nf, nb = _time_loops(node)
                fwd_loops += [f"{rel}::{node.name}"] * nf
                bwd_loops += [f"{rel}::{node.name}"] * nb
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 \
                    and node.module.startswith("flightrecon") and node.module != mod:
                private += [f"{rel}: {node.module}.{a.name}" for a in node.names
                            if a.name.startswith("_") and not a.name.startswith("__")]
        for target, _names in _imports(tree, modules):
            if target in modules and target != mod:
                graph.setdefault(mod, set()).add(target)
                for layer, later in LAYERS:
                    if mod.startswith(layer) and target.startswith(later):
                        against.append(f"{rel} imports {target}")
    print("## time loops (by the shape of their code)")
    print(f"forward filter loops: {len(fwd_loops)}")
    for n in fwd_loops:
        print(f"    {n}")
    print(f"backward smoother loops: {len(bwd_loops)}")
    for n in bwd_loops:
        print(f"    {n}")
    print(f"\n## private names imported from another module of the package: {len(private)}")
    for n in private:
        print(f"    {n}")
    circles = _circles(graph)
    print(f"\n## import circles (module-level and TYPE_CHECKING imports): {len(circles)}")
    for c in circles:
        print(f"    {' <-> '.join(c)}")
    print(f"\n## imports against the data's direction: {len(against)}")
    for n in against:
        print(f"    {n}")
    print()


def main() -> int:
    _structure_report()
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
