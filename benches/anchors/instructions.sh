#!/usr/bin/env bash
# Instruction counts of the mechanics benchmark at two commits, for a before/after comparison
# that does not depend on the machine's load.
#
#   benches/anchors/instructions.sh BEFORE AFTER [FILTER…]
#   REPEAT=5 benches/anchors/instructions.sh …     (runs per count; default 3)
#   BEFORE_BIN=… AFTER_BIN=… benches/anchors/instructions.sh …   (binaries already built)
#
# Wall time on a shared 2-core machine measures the queue as much as the code (the same
# binary varies by ±30 % between runs at load 5–15). Valgrind's instruction count (`I refs`)
# barely does: it varies by a few per cent between runs of the same binary (hash seeds and
# the addresses the interner hashes change the order of the work), so each count is the median
# of REPEAT runs and the spread is printed with it. It does not see cache
# misses or allocator contention, so it complements a quiet-machine criterion run rather than
# replacing it; a change in memory layout can cost time at an equal count.
#
# Each commit's `benches/mechanics.rs` binary is built in release (a temporary worktree, one
# target directory shared by both) and run in criterion's `--test` mode, which runs each
# selected benchmark exactly once. The count of a run that selects nothing (the setup that
# every run shares: building the systems, printing the operation counts) is subtracted, so each
# row is the instructions of one derivation.
#
# Needs valgrind (`apt install valgrind`). Prints a Markdown table (millions of instructions).
set -euo pipefail

before=${1:?usage: instructions.sh BEFORE AFTER [FILTER…]}
after=${2:?usage: instructions.sh BEFORE AFTER [FILTER…]}
shift 2
filters=("$@")
if [ ${#filters[@]} -eq 0 ]; then
    # Rows of 100 M instructions or more: the shared setup subtracted from each count varies by
    # about ±5 M between runs, which swamps a 30 M row such as tidied/10.
    filters=('tidied/30$' 'raw_el/20$' 'legendre/3$')
fi

repo=$(git rev-parse --show-toplevel)
work=$(mktemp -d)
target=${CARGO_TARGET_DIR:-$work/target}
trap 'git -C "$repo" worktree remove --force "$work/tree" >/dev/null 2>&1 || true; rm -rf "$work"' EXIT

build() { # commit -> path of its bench binary
    local rev=$1
    if [ -d "$work/tree" ]; then
        git -C "$work/tree" checkout -q --detach "$rev"
    else
        git -C "$repo" worktree add -q --detach "$work/tree" "$rev"
    fi
    # Cargo keys the root package's fingerprint by its sources' paths and times; touching them
    # makes sure a checkout of another commit is rebuilt.
    find "$work/tree/src" "$work/tree/benches" -name '*.rs' -exec touch {} +
    (cd "$work/tree" && CARGO_TARGET_DIR=$target cargo bench --bench mechanics --no-run \
        --message-format=json 2>/dev/null) |
        python3 -c 'import json,sys
for l in sys.stdin:
    m = json.loads(l)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["name"] == "mechanics":
        print(m["executable"])' | tail -1 | xargs -I{} cp {} "$work/bench-$rev"
    echo "$work/bench-$rev"
}

once() { # binary filter -> instructions of one run
    valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null \
        "$1" --bench --test "$2" 2>&1 | grep 'I *refs' | tail -1 | awk '{gsub(",", "", $NF); print $NF}'
}

counts() { # binary filter -> REPEAT counts, space-separated
    local out=()
    for _ in $(seq "${REPEAT:-3}"); do out+=("$(once "$1" "$2")"); done
    echo "${out[*]}"
}

# BEFORE_BIN / AFTER_BIN: bench binaries already built (skips the two release builds).
b=${BEFORE_BIN:-$(build "$before")}
a=${AFTER_BIN:-$(build "$after")}
base_b=$(counts "$b" 'select_nothing$')
base_a=$(counts "$a" 'select_nothing$')
echo "| benchmark | $before (M instr., median [min, max]) | $after | change of medians |"
echo "|---|---|---|---|"
for f in "${filters[@]}"; do
    python3 - "$f" "$base_b" "$(counts "$b" "$f")" "$base_a" "$(counts "$a" "$f")" <<'PY'
import statistics, sys
f, bb, xb, ba, xa = sys.argv[1:]
def net(base, xs):
    base = statistics.median(map(int, base.split()))
    return [(int(x) - base) / 1e6 for x in xs.split()]
b, a = net(bb, xb), net(ba, xa)
mb, ma = statistics.median(b), statistics.median(a)
print(f"| `{f}` | {mb:.1f} [{min(b):.1f}, {max(b):.1f}] | {ma:.1f} [{min(a):.1f}, {max(a):.1f}] | {(ma - mb) / mb * 100:+.1f} % |")
PY
done
