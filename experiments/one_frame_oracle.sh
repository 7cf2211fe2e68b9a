#!/usr/bin/env bash
# How accurate must a fill be on one real frame (issue 53)? `one_frame.sh` damages FRAME.ply, fills it with each
# METHOD and scores it; then this prints the oracles of `dpcbench oracle` on the same damage: "surface" (one sample
# per missing point on the truth's surface, within half a spacing in its tangent plane) and, per method, "jitter"
# at the method's own measured off-surface error (RMS point-to-plane distance of its fill points): what a fill as
# complete as the truth, but exactly as far off the surface as the method's points, would score; and each
# method's scores inside the hole regions. Usage (the arguments of one_frame.sh):
#   experiments/one_frame_oracle.sh FRAME.ply PRESET SEED OUTDIR [METHOD ...]
# e.g. experiments/one_frame_oracle.sh ../shared/data/8i_longdress_1300/longdress_vox10_1300.ply medium 21 \
#          out/ld-medium fu-nonlocal lozes-pde temporal-fusion
set -euo pipefail
here=$(dirname "$0")
[ $# -ge 4 ] || exec "$here/one_frame.sh"  # prints the usage
frame=$1 seed=$3 out=$4
"$here/one_frame.sh" "$@"
shift 4
methods=("$@")
[ ${#methods[@]} -gt 0 ] || methods=(none lozes-pde temporal-fusion fu-nonlocal)  # one_frame.sh's default
bin=$here/../.venv/bin/dpcbench
holes=$out/damaged/holes.json
echo "== oracles none, surface, truth"
"$bin" oracle "$frame" "$out/damaged" --region "$holes" --seed "$seed"
for m in "${methods[@]}"; do
    [ "$m" = none ] && continue
    echo "== $m: its scores in the hole regions, then the jitter oracle at its off-surface error"
    "$bin" score "$frame" "$out/$m" --region "$holes"
    "$bin" oracle "$frame" "$out/damaged" --region "$holes" --variant jitter --method-result "$out/$m" --seed "$seed"
done
