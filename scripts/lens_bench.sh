#!/bin/bash
# lens_bench.sh OUT [BIN] [SEED] [VARIANTS]: mine-b-mini through sim -> survey -> localize (grid)
# -> eval once per ceiling lens (docs/benchmarks.md, "Lens distortion and another camera"):
#   ideal       the preset (pinhole, no distortion)
#   barrel      plumb_bob k1 = -0.40, k2 = 0.12 on every traverse (strong barrel)
#   fisheye     kannala_brandt, 140 deg equidistant field of view, k1..k4 of order 0.01
#   query-f110  the query traverse's camera with a 10 % longer focal length (89.55 deg HFOV)
#   query-barrel the survey ideal, the query camera plumb_bob k1 = -0.30, k2 = 0.09
# SIM_FROM=DIR reuses DIR/VARIANT/data (an earlier OUT) instead of simulating again.
# Prints one line per variant: the survey's ceiling height and the zigzag query's figures.
set -u
OUT=$1
BIN=${2:-$(cd "$(dirname "$0")/.." && pwd)/build/bin}
SEED=${3:-6}
VARIANTS=${4:-"ideal barrel fisheye query-f110 query-barrel"}
SHARE=$(cd "$(dirname "$0")/.." && pwd)/share/lookup
mkdir -p "$OUT"

scenario() {  # scenario VARIANT FILE: the preset with the variant's camera keys
    local base=$SHARE/scenarios/mine-b-mini.ini extra=""
    case $1 in
        barrel) extra=$'distortion = plumb_bob\ndist_k1 = -0.40\ndist_k2 = 0.12\ndist_p1 = 0.0005\ndist_p2 = -0.0005' ;;
        fisheye) extra=$'distortion = kannala_brandt\nhfov_deg = 140\ndist_k1 = 0.01\ndist_k2 = -0.005\ndist_k3 = 0.002\ndist_k4 = -0.001' ;;
    esac
    # hfov_deg of the preset is replaced, not doubled, when the variant sets it.
    awk -v extra="$extra" '
        /^\[/ { in_cam = ($0 == "[ceiling_camera]") }
        in_cam && extra ~ /hfov_deg/ && /^hfov_deg/ { next }
        { print }
        $0 == "[ceiling_camera]" && extra != "" { print extra }' "$base" > "$2"
    case $1 in
        query-f110) printf '\n[traverse_3.ceiling_camera]\nhfov_deg = 89.55\n' >> "$2" ;;
        query-barrel) printf '\n[traverse_3.ceiling_camera]\ndistortion = plumb_bob\ndist_k1 = -0.30\ndist_k2 = 0.09\n' >> "$2" ;;
    esac
}

for v in $VARIANTS; do
    d=$OUT/$v
    rm -rf "$d"; mkdir -p "$d"
    scenario "$v" "$d/scenario.ini"
    if [ -n "${SIM_FROM:-}" ]; then
        ln -s "$(cd "$SIM_FROM/$v/data" && pwd)" "$d/data"
    else
        "$BIN/lookup-sim" --scenario "$d/scenario.ini" --seed "$SEED" --out "$d/data" -q \
            > "$d/sim.log" 2>&1 || { echo "$v: lookup-sim failed: $(tail -1 "$d/sim.log")"; continue; }
    fi
    "$BIN/lookup-survey" --dataset "$d/data/dataset.ini" --out "$d/db" > "$d/survey.log" 2>&1 ||
        { echo "$v: lookup-survey failed: $(tail -1 "$d/survey.log")"; continue; }
    "$BIN/lookup-localize" --db "$d/db" --rawlog "$d/data/zigzag.rawlog" --out "$d/run-zigzag" \
        --ini "$SHARE/localize-mine-b.ini" --sampling grid > "$d/loc.log" 2>&1 ||
        { echo "$v: lookup-localize failed: $(tail -1 "$d/loc.log")"; continue; }
    "$BIN/lookup-eval" --gt "$d/data/zigzag.rawlog.GT.txt" --runs "$d/run-zigzag" \
        --out "$d/report" > "$d/eval.log" 2>&1
    h=$(python3 -c "import json;c=json.load(open('$d/db/survey_report.json')).get('ceiling',{});print('%.3f'%c.get('ceiling_height_m',0), c.get('triples_used'))")
    row=$(grep '| lookup-grid' "$d/report/report.md" | awk -F'|' '{printf "mean %s p95 %s refined %s after-first %s first %s conf-wrong %s ms/frame %s", $7, $9, $12, $13, $14, $15, $18}')
    echo "$v: ceiling h $h | $row"
done
