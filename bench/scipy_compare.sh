#!/usr/bin/env bash
# Runs the crease benchmark and the SciPy reference solvers on the same exported matrices, in one run.
# Usage: bench/scipy_compare.sh [crease bench flags...]   (e.g. --sizes 100000 --repeats 3)
# Sets up its own Python environment (.venv-bench) with NumPy and SciPy from PyPI.
set -euo pipefail
cd "$(dirname "$0")/.."
out=bench-out
mkdir -p "$out"
if [ ! -x .venv-bench/bin/python ]; then
  python3 -m venv .venv-bench
  .venv-bench/bin/pip install --quiet numpy scipy
fi
cargo build --release --quiet
./target/release/crease bench --export "$out/export" --json "$out/bench.json" "$@"
.venv-bench/bin/python bench/scipy_compare.py "$out/export"
