#!/usr/bin/env bash
# Regenerates pipelines/models/demo-drift-1khz.json, the drift model of pipelines/demo.toml:
# trained on a *simulated* static ADIS16405 log (this tool's fit of the real sensor) at the demo's
# 1 kHz, so that the repository holds no sensor data. Deterministic: same seeds, same file (the
# model's provenance names the simulated log and its SHA-256).
set -euo pipefail
cd "$(dirname "$0")/../.."
log=target/demo-model/adis16405-sim-static-1khz-200s-seed7.csv
mkdir -p "$(dirname "$log")"
cargo run --release --quiet -- simulate --profile adis16405 --rate 1000 --duration 200s \
    --axes 1 --seed 7 -o "$log"
cargo run --release --quiet -- train "$log" --rate 1000 --seed 7 \
    -o pipelines/models/demo-drift-1khz.json
