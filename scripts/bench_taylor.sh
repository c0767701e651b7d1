#!/usr/bin/env bash
# The Taylor benchmarks of BENCHMARKS.md, ours and heyoka's back to back in one run.
# heyoka is installed with pip into a throwaway virtual environment (default
# /tmp/lagrangian-heyoka-venv); if that fails, only our side runs and a note says so.
#   scripts/bench_taylor.sh                 # every section
#   scripts/bench_taylor.sh kepler          # one of: kepler, double-pendulum, step-profile, cold-start, chaos-map
#   HEYOKA_COLD_MAX_N=2 scripts/bench_taylor.sh cold-start   # heyoka: n = 2 only
#   HEYOKA_COLD_UNROLLED_MAX_N=5 scripts/bench_taylor.sh cold-start   # also heyoka's unrolled mode at n = 5
set -uo pipefail
cd "$(dirname "$0")/.."
VENV="${HEYOKA_VENV:-/tmp/lagrangian-heyoka-venv}"
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import heyoka" 2>/dev/null; then
    python3 -m venv "$VENV" && "$VENV/bin/pip" install -q heyoka numpy || echo "NOTE: heyoka could not be installed; its side is skipped"
fi
echo "load: $(cut -d' ' -f1-3 /proc/loadavg)"
if "$VENV/bin/python" -c "import heyoka" 2>/dev/null; then
    "$VENV/bin/python" scripts/bench_taylor_heyoka.py "$@"
fi
# BENCH_PROFILE=dev reuses the tests' build (our code at opt-level 1: slower than the bench
# profile, so our rows are then upper bounds) where the bench profile would rebuild everything.
cargo bench --bench taylor ${BENCH_PROFILE:+--profile "$BENCH_PROFILE"} -- "$@"
echo "load: $(cut -d' ' -f1-3 /proc/loadavg)"
