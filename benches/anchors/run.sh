#!/usr/bin/env bash
# One command for the whole comparison with SymPy, SciPy, SymEngine and heyoka: makes a throwaway virtual environment,
# installs the anchors' packages one by one (an anchor whose install fails is skipped with a
# note), runs `cargo bench --bench pipeline` and every anchor back to back, writes
# benches/anchors/RESULTS.md, and removes the environment.
#
#   benches/anchors/run.sh            # the full run (about 10 minutes on 2 cores)
#   benches/anchors/run.sh --quick    # fewer repeats
set -uo pipefail
cd "$(dirname "$0")/../.."
VENV_DIR=$(mktemp -d)
trap 'rm -rf "$VENV_DIR"' EXIT
python3 -m venv "$VENV_DIR/venv" || { echo "python3 -m venv failed"; exit 1; }
PY="$VENV_DIR/venv/bin/python"
"$PY" -m pip install -q --upgrade pip >/dev/null 2>&1
for pkg in numpy scipy sympy symengine heyoka; do
    "$PY" -m pip install -q "$pkg" || echo "note: pip install $pkg failed; anchors that need it are skipped"
done
"$PY" -m pip freeze | grep -iE '^(numpy|scipy|sympy|symengine|heyoka)==' || true
cargo bench --bench pipeline --no-run || exit 1
"$PY" benches/anchors/run.py "$@"
