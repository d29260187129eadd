#!/bin/sh
# The user's path for one's own gyro (docs/navigation.md, "Your own terms from a short
# record") on simulated units with other terms than the ones the defaults came from: each
# unit's `driftless allan --stage` on its first 30 min of still data against its true terms,
# the same chain (denoise.wavelet -> predict.bias) on the same held-out windows.
#
#   sh docs/scripts/own_terms_units.sh [OUT_DIR]    # about 3 min on 2 cores
#
# Prints per unit the median RMS heading error and ratio to oracle ZARU, own terms then true.
set -eu
B=${DRIFTLESS:-target/release/driftless}
OUT=${1:-target/own-terms-units}
mkdir -p "$OUT"
# name N(deg/sqrt(h)) B(deg/h) K(deg/h/sqrt(h)) R(deg/h^2) seed
UNITS="adis-like 2.3 34 0 0 11
walk-40 2.3 34 40 0 12
quiet 0.5 8 10 0 13
ramp 4 80 0 30 14
walk-150 1.0 5 150 0 15"

chain() { # name, predict.bias keys
    cat <<TOML
name = "$1"
rate_hz = 100.0
axes = 3
input_units = "deg/s"
[[stage]]
name = "sensor"
kind = "ingest.iceoryx2"
input = "sensor/raw"
output = "$1/raw"
[[stage]]
name = "denoise"
kind = "denoise.wavelet"
wavelet = "db6"
level = 5
threshold = "improved"
window = 1024
lag = 64
input = "$1/raw"
output = "$1/denoised"
[[stage]]
name = "predict"
kind = "predict.bias"
input = "$1/denoised"
output = "$1/predicted"
$2
[[stage]]
name = "publish"
kind = "publish"
input = "$1/predicted"
output = "$1/corrected"
TOML
}

echo "$UNITS" | while read -r name n b k r seed; do
    log="$OUT/$name.csv.gz"
    [ -f "$log" ] || "$B" simulate --N "$n" --B "$b" --K "$k" --R "$r" --axes 3 \
        --duration 150min --seed "$seed" -o "$log" 2>/dev/null
    zcat "$log" | head -n 180001 > "$OUT/$name.still.csv"
    own=$("$B" allan "$OUT/$name.still.csv" --rate 100 --stage | grep -E '^(arw|bias_instability|rrw|quantization|lsb) = ')
    chain own "$own" > "$OUT/$name.own.toml"
    chain true "arw = $n
bias_instability = $b
rrw = $k" > "$OUT/$name.true.toml"
    "$B" nav-eval "$log" --rate 100 --characterise 30min \
        --pipeline "$OUT/$name.own.toml" --pipeline "$OUT/$name.true.toml" 2>/dev/null |
        awk -v u="$name" '/^\| all profiles/ {all=1}
            all && /^\| (power-on|[^|]*\.(own|true)\.toml)/ {
            split($0, c, "|"); sub(/ \(.*/, "", c[2]); sub(/.*\//, "", c[2])
            printf "%-10s %-22s %s deg  %sx\n", u, c[2], c[3], c[7] }'
done
