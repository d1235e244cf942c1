#!/usr/bin/env bash
# The built-in example from a fresh machine: install, build, then on the small synthetic mine
# `mine-b-mini`: generate -> survey (laser-derived reference poses) -> train the FCN sample-point
# selector -> localise every query traverse (24-point grid and 12 FCN points) -> evaluate
# against ground truth and print the error table.
# Usage: bash scripts/demo.sh [OUT_DIR]   (default: demo-out)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-demo-out}
PRESET=${LOOKUP_DEMO_PRESET:-mine-b-mini}

bash scripts/install-deps.sh
BUILD_DIR=${LOOKUP_BUILD_DIR:-build}
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$BUILD_DIR" -j "$(nproc)"
BIN="$BUILD_DIR/bin"
DATA="$OUT/$PRESET"
DB="$OUT/$PRESET-db"
START=$(date +%s)

echo "== 1. synthetic mine: lookup-sim --preset $PRESET =="
"$BIN/lookup-sim" --preset "$PRESET" --out "$DATA" --seed 1

# Traverses by role, from dataset.ini.
traverses_with_role() {
    awk -v role="$1" -F' *= *' '
        /^\[traverse_/ { name = ""; rawlog = ""; roles = "" }
        $1 == "name" { name = $2 } $1 == "rawlog" { rawlog = $2 } $1 == "roles" { roles = $2 }
        /^$/ || /^\[/ { if (rawlog != "" && index(roles, role)) print rawlog; if (/^$/) rawlog = "" }
        END { if (rawlog != "" && index(roles, role)) print rawlog }' "$DATA/dataset.ini" | sort -u
}
QUERIES=$(traverses_with_role query)
REFERENCES=$(traverses_with_role reference)

echo "== 2. survey: lookup-survey (ICP-SLAM map + MCL per reference traverse) =="
"$BIN/lookup-survey" --dataset "$DATA/dataset.ini" --out "$DB"

echo "== 3. FCN sample-point selector: lookup-train =="
TRAIN=$(echo "$REFERENCES" | head -n 1)
if [ -x "$BIN/lookup-train" ]; then
    "$BIN/lookup-train" --db "$DB" --train "$DATA/$TRAIN"
else
    echo "(lookup-train not built: LOOKUP_WITH_TORCH=OFF)"
fi

echo "== 4. localise the query traverses: lookup-localize =="
RUNS=()
GTS=()
for q in $QUERIES; do
    stem=${q%.rawlog}
    GTS+=("$DATA/$q.GT.txt")
    "$BIN/lookup-localize" --db "$DB" --rawlog "$DATA/$q" --out "$OUT/runs/$stem-grid24" \
        --sampling grid --method lookup-grid24
    RUNS+=("$OUT/runs/$stem-grid24")
    if grep -q '^directory *= *[^ ]' "$DB/db.ini" 2>/dev/null; then
        "$BIN/lookup-localize" --db "$DB" --rawlog "$DATA/$q" --out "$OUT/runs/$stem-fcn12" \
            --sampling heatmap --method lookup-fcn12
        RUNS+=("$OUT/runs/$stem-fcn12")
    fi
done

echo "== 5. evaluation against ground truth: lookup-eval =="
join() { local IFS=,; echo "$*"; }
"$BIN/lookup-eval" --gt "$(join "${GTS[@]}")" --runs "$(join "${RUNS[@]}")" --out "$OUT/report"
echo "Report: $OUT/report/report.md, chart: $OUT/report/errors.png"
echo "Demo took $(( $(date +%s) - START )) s after the build."
