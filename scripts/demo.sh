#!/usr/bin/env bash
# The built-in example from a fresh machine: install, build, then on the small synthetic mine
# `mine-b-mini`: generate -> survey twice (laser-derived reference poses, and the surveyed
# ground-truth poses) -> train the FCN sample-point selector (short demo training) -> localise
# every query traverse against both databases (24-point grid, 12 FCN points, ORB and ECC
# baselines) -> evaluate against ground truth and print the error table.
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
DB="$OUT/$PRESET-db"        # laser-derived reference poses (what a mine gets)
DB_GT="$OUT/$PRESET-db-gt"  # surveyed (ground-truth) reference poses: refinement alone
case "$PRESET" in
    mine-a*) LOCALIZE_INI=share/lookup/localize-mine-a.ini ;;
    *) LOCALIZE_INI=share/lookup/localize-mine-b.ini ;;
esac
TRAIN_INI=${LOOKUP_DEMO_TRAIN_INI:-share/lookup/train-demo.ini}
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
"$BIN/lookup-survey" --dataset "$DATA/dataset.ini" --poses ground-truth --out "$DB_GT"

echo "== 3. FCN sample-point selector: lookup-train =="
TRAIN=$(echo "$REFERENCES" | head -n 1)
if [ -x "$BIN/lookup-train" ]; then
    # Trained once on the surveyed database, the model scores any database's references.
    "$BIN/lookup-train" --db "$DB_GT" --train "$DATA/$TRAIN" --ini "$TRAIN_INI"
    "$BIN/lookup-train" --db "$DB" --heatmaps-only "$DB_GT/fcn_model.pt"
else
    echo "(lookup-train not built: LOOKUP_WITH_TORCH=OFF)"
fi

echo "== 4. localise the query traverses: lookup-localize =="
RUNS=()
GTS=()
localize() {  # localize DB QUERY RUN_NAME METHOD [extra flags]
    local db=$1 q=$2 name=$3 method=$4
    shift 4
    "$BIN/lookup-localize" --db "$db" --rawlog "$DATA/$q" --out "$OUT/runs/$name" \
        --ini "$LOCALIZE_INI" --method "$method" "$@"
    RUNS+=("$OUT/runs/$name")
}
for q in $QUERIES; do
    stem=${q%.rawlog}
    GTS+=("$DATA/$q.GT.txt")
    for db in "$DB_GT" "$DB"; do
        tag=$([ "$db" = "$DB" ] && echo laser || echo surveyed)
        localize "$db" "$q" "$stem-$tag-grid24" "$tag-lookup-grid24" --sampling grid
        if grep -q '^directory *= *[^ ]' "$db/db.ini" 2>/dev/null; then
            localize "$db" "$q" "$stem-$tag-fcn12" "$tag-lookup-fcn12" --sampling heatmap
        fi
        localize "$db" "$q" "$stem-$tag-orb" "$tag-orb-ransac" --sampling grid --matcher orb
        localize "$db" "$q" "$stem-$tag-ecc" "$tag-ecc" --sampling grid --matcher ecc
    done
done

echo "== 5. evaluation against ground truth: lookup-eval =="
join() { local IFS=,; echo "$*"; }
"$BIN/lookup-eval" --gt "$(join "${GTS[@]}")" --runs "$(join "${RUNS[@]}")" --out "$OUT/report" \
    --map "$DATA/map.gridmap.gz"
echo "Report: $OUT/report/report.md, charts: $OUT/report/errors.png, trajectory_*.png," \
    "error_along_*.png"
echo "Demo took $(( $(date +%s) - START )) s after the build."
