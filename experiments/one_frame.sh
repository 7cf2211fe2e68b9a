#!/usr/bin/env bash
# One real frame, no other frame to copy from (issue 53): damage it with region holes, fill it with each method,
# score the whole frame (D1, D2, NSHD, ...). Usage:
#   experiments/one_frame.sh FRAME.ply PRESET SEED OUTDIR [METHOD ...]
# e.g. experiments/one_frame.sh ../shared/data/8i_longdress_1300/longdress_vox10_1300.ply medium 21 \
#          out/ld-medium none lozes-pde temporal-fusion fu-nonlocal
# Prints one score table per method and writes OUTDIR/<method>.json (dpcbench score --json).
set -euo pipefail
if [ $# -lt 4 ]; then
    echo "usage: $0 FRAME.ply PRESET SEED OUTDIR [METHOD ...]" >&2
    exit 2
fi
frame=$1 preset=$2 seed=$3 out=$4
shift 4
methods=("$@")
[ ${#methods[@]} -gt 0 ] || methods=(none lozes-pde temporal-fusion fu-nonlocal)
bin=$(dirname "$0")/../.venv/bin/dpcbench
mkdir -p "$out"
"$bin" damage "$frame" --holes region --param preset="$preset" --seed "$seed" --out "$out/damaged" --overwrite
for m in "${methods[@]}"; do
    start=$(date +%s)
    "$bin" inpaint "$out/damaged" --method "$m" --regions "$out/damaged/holes.json" --out "$out/$m"
    echo "== $m ($(($(date +%s) - start)) s wall)"
    "$bin" score "$frame" "$out/$m" --json > "$out/$m.json"
    "$bin" score "$frame" "$out/$m"
done
