#!/usr/bin/env bash
# Large inputs against SymEngine: `cargo bench ${CARGO_PROFILE:+--profile "$CARGO_PROFILE"} --bench robust` and SymEngine (in a throwaway virtual
# environment) on the same inputs, back to back in one run.
#
#   benches/anchors/robust_symengine.sh                     # bench profile (release)
#   CARGO_PROFILE=dev benches/anchors/robust_symengine.sh   # dev profile: no release build
set -uo pipefail
cd "$(dirname "$0")/../.."
VENV_DIR=$(mktemp -d)
trap 'rm -rf "$VENV_DIR"' EXIT
python3 -m venv "$VENV_DIR/venv" || { echo "python3 -m venv failed"; exit 1; }
PY="$VENV_DIR/venv/bin/python"
"$PY" -m pip install -q symengine || { echo "pip install symengine failed"; exit 1; }
"$PY" -m pip freeze | grep -i '^symengine=='
echo "load: $(cut -d' ' -f1-3 /proc/loadavg)"
cargo bench ${CARGO_PROFILE:+--profile "$CARGO_PROFILE"} --bench robust
"$PY" benches/anchors/robust_symengine.py
# The 10⁵-term sum last, alone, under a cap (SYMENGINE_CAP seconds, default 300).
CAP=${SYMENGINE_CAP:-300}
timeout "$CAP" "$PY" benches/anchors/robust_symengine.py sum ||
    echo "symengine/sum_1e5_parse_diff did not finish within $CAP s (stopped)"
echo "load: $(cut -d' ' -f1-3 /proc/loadavg)"
