#!/usr/bin/env bash
# Instruction counts of the mechanics benchmark at two commits, for a before/after comparison
# that does not depend on the machine's load.
#
#   benches/anchors/instructions.sh BEFORE AFTER [FILTER…]
#
# Wall time on a shared 2-core machine measures the queue as much as the code (the same
# binary varies by ±30 % between runs at load 5–15). Valgrind's instruction count (`I refs`)
# does not: it is the same on every run of the same binary and input. It does not see cache
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
    filters=('tidied/10$' 'tidied/30$' 'raw_el/20$' 'legendre/3$')
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

count() { # binary filter -> instructions
    valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null \
        "$1" --bench --test "$2" 2>&1 | grep 'I *refs' | tail -1 | awk '{gsub(",", "", $NF); print $NF}'
}

b=$(build "$before")
a=$(build "$after")
base_b=$(count "$b" 'select_nothing$')
base_a=$(count "$a" 'select_nothing$')
echo "| benchmark | $before (M instr.) | $after (M instr.) | change |"
echo "|---|---|---|---|"
for f in "${filters[@]}"; do
    nb=$(( $(count "$b" "$f") - base_b ))
    na=$(( $(count "$a" "$f") - base_a ))
    python3 -c "print(f'| \`$f\` | {$nb/1e6:.1f} | {$na/1e6:.1f} | {($na-$nb)/$nb*100:+.1f} % |')"
done
