#!/usr/bin/env bash
# The refusal oracle (`dpcbench oracle --method-result R --refusal ...`) on every D-FAUST coherent-hole damage of the
# margin presets: the tuning row (frames 0-9, seeds 0-2) and the held-out rows (frames 0-9 seeds 3-4; frames 10-16
# seeds 5-6; frames 0-16 every second frame, seeds 7-8). Per damage: the results of temporal-fusion, fu-nonlocal and
# temporal-graph (registry defaults; the other two are the best other methods on D1 on these rows in
# results/margins), the better of the two others' mean D1, and the means of temporal-fusion's result as it is and
# refusing its fill points at least 0.5, 0.75 and 1 spacings off the truth, against the targets (D1 >= that + 1 dB,
# D2 >= no fill's).
#
#   bash experiments/refusal_rows.sh OUTDIR [JOBS]     # about 4 minutes a damage on one core; JOBS damages at once
#
# Prints one line a damage, and writes each damage's files under OUTDIR/<rows>-<seed>/.
set -euo pipefail
source "$(dirname "$0")/_rows.sh"
data=$dfaust

one() {  # NAME FRAMES SEED
    local dir=$out/$1-$3
    mkdir -p "$dir"
    # what a run before made is kept: a damage with its holes.json, a result with a frame per damaged frame
    [ -f "$dir/damaged/holes.json" ] ||
        "$bin" damage "$data" --holes region --param preset=medium --param coherent=true --seed "$3" --frames "$2" \
            --out "$dir/damaged" --overwrite > /dev/null 2>&1
    local count
    count=$(ls "$dir/damaged"/*.ply | wc -l)
    # the truth frames the damage was made from, in its order
    "$python" "$root/experiments/_truth_links.py" "$dir" "$data"
    for m in temporal-fusion fu-nonlocal temporal-graph; do
        [ "$(ls "$dir/$m"/*.ply 2> /dev/null | wc -l)" = "$count" ] ||
            "$bin" inpaint "$dir/damaged" --method "$m" --regions "$dir/damaged/holes.json" --out "$dir/$m" \
                --overwrite > /dev/null 2>&1
    done
    for m in fu-nonlocal temporal-graph; do
        "$bin" score "$dir/truth" "$dir/$m" --json > "$dir/$m.json" 2> /dev/null
    done
    "$bin" oracle "$dir/truth" "$dir/damaged" --method-result "$dir/temporal-fusion" --refusal 0.5,0.75,1 \
        --variant none --json > "$dir/oracle.json" 2> /dev/null
    "$python" - "$1" "$3" "$dir" <<'EOF'
import json, sys
from pathlib import Path
rows, seed, d = sys.argv[1], sys.argv[2], Path(sys.argv[3])
others = {m: json.loads((d / f"{m}.json").read_text())["mean"]["gpsnr_d1"] for m in ("fu-nonlocal", "temporal-graph")}
best = max(others, key=others.get)
other = others[best]
oracle = json.loads((d / "oracle.json").read_text())
none_d2 = oracle["variants"]["none"]["frame"]["gpsnr_d2"]
cells = []
for label, scores in oracle["refusal"].items():
    d1, d2 = scores["frame"]["gpsnr_d1"], scores["frame"]["gpsnr_d2"]
    met = "both" if d1 >= other + 1 and d2 >= none_d2 else ("D1" if d1 >= other + 1 else ("D2" if d2 >= none_d2 else "-"))
    cells.append(f"{label} {d1:.2f}/{d2:.2f} ({met})")
print(f"{rows} seed {seed}: {best} D1 {other:.2f}, no fill D2 {none_d2:.2f}; " + "; ".join(cells), flush=True)
EOF
}

export -f one
export out bin python data root
printf "%s\n" "frames-0-9 0-9 0" "frames-0-9 0-9 1" "frames-0-9 0-9 2" "frames-0-9 0-9 3" "frames-0-9 0-9 4" \
    "frames-10-16 10-16 5" "frames-10-16 10-16 6" "every-2nd 0,2,4,6,8,10,12,14,16 7" \
    "every-2nd 0,2,4,6,8,10,12,14,16 8" | xargs -P "$jobs" -L 1 bash -c 'one "$0" "$1" "$2"'
