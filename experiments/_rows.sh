# Sourced by the row scripts here (refusal_rows.sh, depth_rows.sh): their arguments OUTDIR [JOBS], the checkout's
# dpcbench and python, and the D-FAUST capture beside the checkout (../shared).
if [ $# -lt 1 ]; then
    echo "usage: $0 OUTDIR [JOBS]" >&2
    exit 2
fi
out=$1 jobs=${2:-1}
root=$(cd "$(dirname "$0")/.." && pwd)
bin=$root/.venv/bin/dpcbench
python=$root/.venv/bin/python
dfaust=$root/../shared/data/dfaust_50004_punching
[ -d "$dfaust" ] || { echo "error: $dfaust not found; run from a checkout with ../shared beside it" >&2; exit 2; }
mkdir -p "$out"
