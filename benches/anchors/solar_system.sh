#!/usr/bin/env bash
# The outer-solar-system comparison with REBOUND (benches/anchors/solar_system.py) in a
# throwaway virtual environment; builds the release binary first.
set -euo pipefail
cd "$(dirname "$0")/../.."
VENV_DIR=$(mktemp -d)
trap 'rm -rf "$VENV_DIR"' EXIT
python3 -m venv "$VENV_DIR/venv"
"$VENV_DIR/venv/bin/pip" install -q rebound
cargo build --release --bin lagrangian
"$VENV_DIR/venv/bin/python" benches/anchors/solar_system.py
