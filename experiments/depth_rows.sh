#!/usr/bin/env bash
# How far each spatial method's fill lies off the truth by how deep into the hole it lies (`dpcbench oracle
# --method-result R --by-depth`), on tuning and held-out rows of the margin presets where temporal-fusion's D2 is
# below no fill's or its fill is spatial: D-FAUST coherent holes (frames 0-9 seed 0, tuning; frames 10-16 seed 5,
# held out), D-FAUST occlusion boxes (frames 0-9 seed 0, tuning) and the walking cow's occlusion rig (size small, 10
# frames, voxelized and as float samples, seed 0, held out). Methods: temporal-fusion, lozes-pde, fu-nonlocal,
# temporal-graph at their registry defaults.
#
#   bash experiments/depth_rows.sh OUTDIR [JOBS]     # about 45 minutes on one core; JOBS rows at once
#
# Prints per row and method its fill points by depth bin (spacings from the damaged frame): count and off-surface RMS
# in spacings, with each method's mean whole-frame D1 / D2 and no fill's D2. Writes each row's files under
# OUTDIR/<row>/ and keeps what a run before made.
set -euo pipefail
source "$(dirname "$0")/_rows.sh"

one() {  # ROW SOURCE FRAMES HOLES SEED [GENERATE PARAMS...]
    local row=$1 dir=$out/$1 source=$2 frames=$3 holes=$4 seed=$5
    shift 5  # what is left: the cow's generate parameters
    mkdir -p "$dir"
    if [ "$source" = cow ]; then
        # the embedded stand-in: its frames are the truth
        [ -f "$dir/truth/cow_0009.ply" ] ||
            "$bin" generate cow --frames "$frames" "$@" --out "$dir/truth" --overwrite > /dev/null 2>&1
        [ -f "$dir/damaged/holes.json" ] ||
            "$bin" damage "$dir/truth" --holes "$holes" --seed "$seed" --out "$dir/damaged" --overwrite \
                > /dev/null 2>&1
    else
        local args=(--holes region --param preset=medium --param coherent=true)
        [ "$holes" = occlusion ] && args=(--holes occlusion)
        [ -f "$dir/damaged/holes.json" ] ||
            "$bin" damage "$source" "${args[@]}" --seed "$seed" --frames "$frames" --out "$dir/damaged" \
                --overwrite > /dev/null 2>&1
        # the truth frames the damage was made from, in its order
        "$python" "$root/experiments/_truth_links.py" "$dir" "$source"
    fi
    local count
    count=$(ls "$dir/damaged"/*.ply | wc -l)
    for m in temporal-fusion lozes-pde fu-nonlocal temporal-graph; do
        [ "$(ls "$dir/$m"/*.ply 2> /dev/null | wc -l)" = "$count" ] ||
            "$bin" inpaint "$dir/damaged" --method "$m" --regions "$dir/damaged/holes.json" --out "$dir/$m" \
                --overwrite > /dev/null 2>&1
        "$bin" oracle "$dir/truth" "$dir/damaged" --method-result "$dir/$m" --by-depth --variant none --json \
            > "$dir/$m.depth.json" 2> /dev/null
        "$bin" score "$dir/truth" "$dir/$m" --json > "$dir/$m.json" 2> /dev/null
    done
    "$python" - "$row" "$dir" <<'EOF'
import json, sys
from pathlib import Path
row, d = sys.argv[1], Path(sys.argv[2])
lines = []
for m in ("temporal-fusion", "lozes-pde", "fu-nonlocal", "temporal-graph"):
    depth = json.loads((d / f"{m}.depth.json").read_text())
    score = json.loads((d / f"{m}.json").read_text())["mean"]
    bins = "; ".join(f"{b['low']:g}-{'' if b['high'] is None else format(b['high'], 'g')} s: {b['points']} at "
                     f"{b['off_rms']:.2f}" for b in depth["by_depth"])
    lines.append(f"  {m}: D1 / D2 {score['gpsnr_d1']:.2f} / {score['gpsnr_d2']:.2f}; {bins}")
none_d2 = depth["variants"]["none"]["frame"]["gpsnr_d2"]
print(f"{row} (no fill D2 {none_d2:.2f}):\n" + "\n".join(lines), flush=True)
EOF
}

export -f one
export out bin python root
printf "%s\n" "dfaust-coherent-0-9-seed0 $dfaust 0-9 coherent 0" \
    "dfaust-coherent-10-16-seed5 $dfaust 10-16 coherent 5" \
    "dfaust-occlusion-0-9-seed0 $dfaust 0-9 occlusion 0" \
    "cow-voxelized-occlusion-seed0 cow 10 occlusion 0 --param size=small" \
    "cow-float-occlusion-seed0 cow 10 occlusion 0 --param size=small --param bit_depth=none" |
    xargs -P "$jobs" -L 1 bash -c 'one "$@"' _
