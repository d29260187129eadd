#!/usr/bin/env bash
# Fuzz one target for a given time (default 600 s) with the seed corpus in fuzz/corpus/TARGET.
#   fuzz/run.sh pipeline_toml 600
#   fuzz/run.sh model_json 600
#   fuzz/run.sh csv 600
#   fuzz/run.sh csv_gz 600
#   fuzz/run.sh recording 600
# Needs `cargo install cargo-fuzz`. The stable toolchain is the only one on our machines:
# RUSTC_BOOTSTRAP lets cargo-fuzz pass its flags, and `-s none` skips the sanitizer (which
# needs a nightly standard library). New inputs go to fuzz/corpus-new/TARGET (not committed);
# a crash is written to fuzz/artifacts/TARGET: turn it into a case of tests/fuzz_regressions.rs.
set -euo pipefail
target=${1:?target: pipeline_toml, model_json, csv, csv_gz or recording}
seconds=${2:-600}
cd "$(dirname "$0")"
mkdir -p "corpus-new/$target"
RUSTC_BOOTSTRAP=1 cargo fuzz run -O -s none "$target" "corpus-new/$target" "corpus/$target" -- \
  -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 -max_len=65536 \
  -print_final_stats=1
