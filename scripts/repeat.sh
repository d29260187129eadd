#!/usr/bin/env bash
# Run one cargo test target N times in a row and stop at the first failure, optionally with a
# CPU hog on every core beside it (a test that depends on the machine's scheduling shows here).
#
#   scripts/repeat.sh 20 cleanup_safety            # tests/cleanup_safety.rs, 20 times
#   HOG=1 scripts/repeat.sh 20 daemon              # the same with a busy loop on each core
#   scripts/repeat.sh 10 ros2_live --features ros2 # cargo options after the target
set -euo pipefail
cd "$(dirname "$0")/.."
n="${1:?usage: scripts/repeat.sh N TEST_TARGET [cargo test args...]}"
target="${2:?usage: scripts/repeat.sh N TEST_TARGET [cargo test args...]}"
shift 2
cargo test --release --test "$target" --no-run --quiet "$@"
hogs=()
if [[ "${HOG:-0}" == 1 ]]; then
    for _ in $(seq "$(nproc)"); do
        (while :; do :; done) &
        hogs+=($!)
    done
    trap 'kill "${hogs[@]}" 2>/dev/null' EXIT
fi
for i in $(seq "$n"); do
    if ! out=$(cargo test --release --quiet --test "$target" "$@" 2>&1); then
        echo "$out"
        echo "run $i of $n FAILED"
        exit 1
    fi
    echo "run $i of $n: ok"
done
