#!/usr/bin/env bash
# Colour PSNR of every method on one real frame (issue 54): damage FRAME.ply with region holes (as one_frame.sh),
# fill it with each METHOD (`dpcbench inpaint`, colour fill COLOUR, default auto: each method's own colours), and
# print one Markdown row per method: cpsnr_y / cpsnr_u / cpsnr_v inside the hole regions, cpsnr_y of the whole
# frame, and the inpaint wall seconds. Usage:
#   experiments/colour_one_frame.sh FRAME.ply PRESET SEED OUTDIR [METHOD ...]
# e.g. experiments/colour_one_frame.sh ../shared/data/8i_longdress_1300/longdress_vox10_1300.ply medium 21 out/ld-colour
# DPCBENCH=/path/to/.venv/bin/dpcbench runs another install (main's, for a before/after table); COLOUR=nearest
# colours every new point by its nearest input point (the reference fill).
set -euo pipefail
if [ $# -lt 4 ]; then
    echo "usage: $0 FRAME.ply PRESET SEED OUTDIR [METHOD ...]" >&2
    exit 2
fi
frame=$1 preset=$2 seed=$3 out=$4
shift 4
methods=("$@")
[ ${#methods[@]} -gt 0 ] || methods=(none lozes-pde meshlab fu-nonlocal temporal-graph temporal-fusion)
bin=${DPCBENCH:-$(dirname "$0")/../.venv/bin/dpcbench}
colour=${COLOUR:-auto}
mkdir -p "$out"
"$bin" damage "$frame" --holes region --param preset="$preset" --seed "$seed" --out "$out/damaged" --overwrite >&2
echo "| method | holes Y | holes U | holes V | frame Y | inpaint s |"
echo "|---|---|---|---|---|---|"
for m in "${methods[@]}"; do
    start=$(date +%s)
    "$bin" inpaint "$out/damaged" --method "$m" --regions "$out/damaged/holes.json" --out "$out/$m" --colour "$colour" \
        --overwrite >&2
    seconds=$(($(date +%s) - start))
    "$bin" score "$frame" "$out/$m" --region "$out/damaged/holes.json" --metric cpsnr_y --metric cpsnr_u \
        --metric cpsnr_v --json > "$out/$m.holes.json"
    "$bin" score "$frame" "$out/$m" --metric cpsnr_y --json > "$out/$m.frame.json"
    python3 - "$out/$m.holes.json" "$out/$m.frame.json" "$m" "$seconds" <<'PY'
import json, sys
holes, frame = (json.load(open(p))["mean"] for p in sys.argv[1:3])
print(f"| {sys.argv[3]} | {holes['cpsnr_y']:.2f} | {holes['cpsnr_u']:.2f} | {holes['cpsnr_v']:.2f} | "
      f"{frame['cpsnr_y']:.2f} | {sys.argv[4]} |", flush=True)
PY
done
