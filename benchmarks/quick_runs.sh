#!/usr/bin/env bash
# Everyday commands on the 15-minute circuit sample, two versions of the package interleaved
# (docs/performance.md, "quick everyday runs"): `info` and a warm `reconstruct`, ROUNDS rounds
# of base info, base reconstruct, new info, new reconstruct, each under /usr/bin/time -v.
#
#   benchmarks/quick_runs.sh BASE_DIR NEW_DIR [ROUNDS]
#
# BASE_DIR and NEW_DIR each hold a `flightrecon/` package (a worktree, or
# `git archive <commit> flightrecon | tar -x -C DIR`); both run through the current Python
# from a scratch folder outside every checkout (`python -m` puts the current folder first on
# sys.path). Prints one tab-separated line per run: round, version, command, wall [s],
# user [s], system [s], peak RSS [KiB], load average; then the medians and their ratios.
set -eu
base=$(cd "$1" && pwd)
new=$(cd "$2" && pwd)
rounds=${3:-5}
py=$(command -v python)
here=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
cp "$here/sample_logs/circuit.parquet" "$here/sample_logs/circuit.meta.toml" "$work/"
cd "$work"
unset PYTHONDONTWRITEBYTECODE   # as a user runs it: bytecode cached after the first run
for v in base new; do
  dir=$base; [ $v = new ] && dir=$new
  found=$(PYTHONPATH=$dir "$py" -c "import flightrecon; print(flightrecon.__file__)")
  case $found in "$dir"/*) ;; *) echo "the $v run imports $found, not $dir" >&2; exit 2;; esac
  # warm-up: bytecode written, kernels compiled into that package's cache
  PYTHONPATH=$dir "$py" -m flightrecon --quiet reconstruct circuit.parquet -o warm-$v.parquet \
    > /dev/null 2>&1
done
runs=$work/runs.tsv
for i in $(seq "$rounds"); do
  for v in base new; do
    dir=$base; [ $v = new ] && dir=$new
    for cmd in info reconstruct; do
      if [ $cmd = info ]; then args="info circuit.parquet"
      else args="--quiet reconstruct circuit.parquet -o run-$v.parquet"; fi
      # shellcheck disable=SC2086
      PYTHONPATH=$dir /usr/bin/time -v "$py" -m flightrecon $args > /dev/null 2> tv.txt
      w=$(awk '/Elapsed \(wall/ {print $NF}' tv.txt)
      u=$(awk '/User time/ {print $NF}' tv.txt)
      s=$(awk '/System time/ {print $NF}' tv.txt)
      m=$(awk '/Maximum resident/ {print $NF}' tv.txt)
      printf "%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n" "$i" $v $cmd "$w" "$u" "$s" "$m" \
        "$(cut -d' ' -f1 /proc/loadavg)" | tee -a "$runs"
    done
  done
done
"$py" - "$runs" <<'EOF'
import statistics as st
import sys

rows = [line.split("\t") for line in open(sys.argv[1]).read().splitlines()]


def seconds(text: str) -> float:
    parts = [float(p) for p in text.split(":")]
    return sum(p * 60 ** k for k, p in enumerate(reversed(parts)))


for cmd in ("info", "reconstruct"):
    med = {}
    for v in ("base", "new"):
        r = [x for x in rows if x[1] == v and x[2] == cmd]
        med[v] = (st.median(seconds(x[3]) for x in r),
                  st.median(float(x[4]) + float(x[5]) for x in r),
                  st.median(int(x[6]) for x in r) / 1024)
    print(f"{cmd}: wall {med['base'][0]:.2f} -> {med['new'][0]:.2f} s "
          f"({med['new'][0] / med['base'][0]:.2f}), CPU {med['base'][1]:.2f} -> "
          f"{med['new'][1]:.2f} s ({med['new'][1] / med['base'][1]:.2f}), peak "
          f"{med['base'][2]:.0f} -> {med['new'][2]:.0f} MiB")
EOF
