#!/usr/bin/env bash
# Builds the package with the release profile into its own virtual environment and runs
# bench.py (the Python rows of BENCHMARKS.md; heyoka.py is installed into the same throwaway
# environment for the rows measured against it). Usage: bash python/benchmarks/run.sh [script]
# (default bench.py; batch.py: issue 28's ensemble rows against heyoka's batch mode)
set -euo pipefail
cd "$(dirname "$0")/../.."
export CARGO_TARGET_DIR="$PWD/target"
venv="$CARGO_TARGET_DIR/python-bench-venv"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
export PATH="$venv/bin:$PATH"  # the build backend runs the venv's `maturin`
"$venv/bin/pip" install --quiet --disable-pip-version-check maturin numpy scipy sympy "dask[distributed]" heyoka
MATURIN_PEP517_ARGS="--profile release" "$venv/bin/pip" install --quiet --disable-pip-version-check --no-build-isolation --force-reinstall --no-deps ./python
"$venv/bin/python" "python/benchmarks/${1:-bench.py}"
