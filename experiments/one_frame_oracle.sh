#!/usr/bin/env bash
# How accurate must a fill be on one real frame (issue 53)? Damages FRAME.ply with region holes, fills it with
# each METHOD and prints, beside the method's own whole-frame and hole-region scores, the oracles of
# `dpcbench oracle`: "surface" (one sample per missing point on the truth's surface, within half a spacing in
# its tangent plane) and "jitter" (the missing truth points moved along the truth normal by the method's own
# measured off-surface error, RMS point-to-plane distance of its fill points): what a fill as complete as the
# truth, but exactly as far off the surface as the method's points, would score. Usage:
#   experiments/one_frame_oracle.sh FRAME.ply PRESET SEED OUTDIR [METHOD ...]
# e.g. experiments/one_frame_oracle.sh ../shared/data/8i_longdress_1300/longdress_vox10_1300.ply medium 21 \
#          out/ld-medium fu-nonlocal lozes-pde temporal-fusion
set -euo pipefail
if [ $# -lt 4 ]; then
    echo "usage: $0 FRAME.ply PRESET SEED OUTDIR [METHOD ...]" >&2
    exit 2
fi
frame=$1 preset=$2 seed=$3 out=$4
shift 4
methods=("$@")
[ ${#methods[@]} -gt 0 ] || methods=(fu-nonlocal lozes-pde temporal-fusion)
bin=$(dirname "$0")/../.venv/bin/dpcbench
mkdir -p "$out"
"$bin" damage "$frame" --holes region --param preset="$preset" --seed "$seed" --out "$out/damaged" --overwrite
echo "== oracles none, surface, truth"
"$bin" oracle "$frame" "$out/damaged" --region "$out/damaged/holes.json" --seed "$seed"
for m in "${methods[@]}"; do
    "$bin" inpaint "$out/damaged" --method "$m" --regions "$out/damaged/holes.json" --out "$out/$m" --overwrite
    echo "== $m: its scores, then the jitter oracle at its off-surface error"
    "$bin" score "$frame" "$out/$m"
    "$bin" score "$frame" "$out/$m" --region "$out/damaged/holes.json"
    "$bin" oracle "$frame" "$out/damaged" --region "$out/damaged/holes.json" --variant jitter --method-result "$out/$m" \
        --seed "$seed"
done
