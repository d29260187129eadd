#!/usr/bin/env bash
# The flake check of issue 41: every test target that starts a daemon (or the targets named),
# N runs in a row each (default 20), with a busy loop on every core beside them. Stops at the
# first failure and prints its output. A test that needs the machine to be quick fails here.
#
#   scripts/hog_loop.sh                  # every daemon test, 20 runs each (an hour or more)
#   scripts/hog_loop.sh 20 no_alloc stop_signal users
set -euo pipefail
cd "$(dirname "$0")/.."
n="${1:-20}"
shift || true
if [[ $# -gt 0 ]]; then
    targets=("$@")
else
    # A target starts a daemon if it runs `driftless run` or the runtime itself. bridge and
    # ros2_live need their cargo features: scripts/repeat.sh 20 bridge --features zenoh.
    mapfile -t targets < <(grep -l -E 'wait_ready\(|start\(|run_command\(|spawn_run|"run",|runtime::\{run' tests/*.rs |
        xargs -n1 basename | sed 's/\.rs$//' | grep -v -x -E 'bridge|ros2_live' | sort)
fi
hogs=()
for _ in $(seq "$(nproc)"); do
    (while :; do :; done) &
    hogs+=($!)
done
trap 'kill "${hogs[@]}" 2>/dev/null' EXIT
echo "under $(nproc) busy loops, $n runs each: ${targets[*]}"
for t in "${targets[@]}"; do
    if ! out=$(scripts/repeat.sh "$n" "$t" 2>&1); then
        echo "$out"
        echo "$t: FAILED under load"
        exit 1
    fi
    echo "$t: $(echo "$out" | tail -1)"
done
echo "all ${#targets[@]} targets passed $n runs in a row"
