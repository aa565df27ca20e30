#!/usr/bin/env bash
# One command from nothing to the shipped models (see train/README.md):
#
#   train/run.sh                     # sim frames (needs mgmot-sim's `render`)
#   MGMOT_TRAIN_SOURCE=procedural train/run.sh   # stand-in data, provisional model
#
# Environment knobs (defaults in brackets):
#   MGMOT_TRAIN_SOURCE   sim | procedural                      [sim]
#   MGMOT_TRAIN_MINUTES  wall-clock training budget             [45]
#   MGMOT_TRAIN_FRAMES   minimum training frames to render      [5000]
#   MGMOT_TRAIN_EVERY    keep every Nth rendered frame          [5]
#   MGMOT_TRAIN_INSTALL  1 = copy models + metrics into models/ [0]
# Seeds: training renders use seeds 1.., held-out renders 100001.. (disjoint),
# procedural frames 0..FRAMES-1 for training and 1000000.. for held-out;
# torch / numpy are seeded with 1 (train.py --seed).
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/.." && pwd)"
SOURCE="${MGMOT_TRAIN_SOURCE:-sim}"
MINUTES="${MGMOT_TRAIN_MINUTES:-45}"
FRAMES="${MGMOT_TRAIN_FRAMES:-5000}"
EVERY="${MGMOT_TRAIN_EVERY:-5}"   # keep every Nth frame of a sequence (decorrelated frames)
RUN="$HERE/runs/$SOURCE"
DATA="$HERE/data/sim"
SCENARIOS=(calm_baseline high_altitude_tiny swimmer_group boats_crossing fast_drone gimbal_swings leave_and_return mixed_mission_soak)
mkdir -p "$RUN"

# 1. Python environment (pinned).
if [[ ! -x "$HERE/.venv/bin/python" ]]; then
    python3 -m venv "$HERE/.venv"
    "$HERE/.venv/bin/pip" install --quiet -r "$HERE/requirements.txt"
fi
PY="$HERE/.venv/bin/python"
cd "$HERE"

# 2. Data.
count_frames() { find "$1" -name '*.png' 2>/dev/null | wc -l; }
if [[ "$SOURCE" == sim ]]; then
    (cd "$ROOT" && cargo build --release -p mgmot-sim)
    SIM="$ROOT/target/release/mgmot-sim"
    "$SIM" render --help >/dev/null 2>&1 || { echo "mgmot-sim has no 'render' subcommand yet: merge main once the simulator lands" >&2; exit 2; }
    seed=1
    while (( $(count_frames "$DATA/train") < FRAMES )); do
        for sc in "${SCENARIOS[@]}"; do
            out="$DATA/train/${sc}_s${seed}"
            [[ -d "$out" ]] || "$SIM" render -s "$sc" --seed "$seed" -o "$out" --format png --every "$EVERY"
        done
        seed=$((seed + 1))
    done
    for sc in "${SCENARIOS[@]}"; do
        out="$DATA/heldout/${sc}_s100001"
        [[ -d "$out" ]] || "$SIM" render -s "$sc" --seed 100001 -o "$out" --format png --every "$EVERY"
    done
    TRAIN_ARGS=(--source sim --data "$DATA/train")
    CAL_ARGS=(--source sim --data "$DATA/train")
    EVAL_ARGS=(--source sim --data "$DATA/heldout" --count 1000)
else
    TRAIN_ARGS=(--source procedural --frames 2000 --seed-base 0)
    CAL_ARGS=(--source procedural --seed-base 0)
    EVAL_ARGS=(--source procedural --seed-base 1000000 --count 300)
fi

# 3. Train (time-bounded), 4. export fp32, 5. quantise int8, 6. evaluate both.
"$PY" train.py "${TRAIN_ARGS[@]}" --crop 192 --batch 8 --minutes "$MINUTES" --seed 1 --out "$RUN/tinydet.pt"
"$PY" export.py --ckpt "$RUN/tinydet.pt" --size 320 --out "$RUN/mgmot-det-fp32.onnx" \
    --description "mgmot TinyDet swimmer/boat detector, trained on $SOURCE frames"
"$PY" quantize.py --fp32 "$RUN/mgmot-det-fp32.onnx" --out "$RUN/mgmot-det-int8.onnx" "${CAL_ARGS[@]}" --count 128
"$PY" evaluate.py --models "$RUN/mgmot-det-fp32.onnx" "$RUN/mgmot-det-int8.onnx" "${EVAL_ARGS[@]}" --json "$RUN/metrics.json"

if [[ "${MGMOT_TRAIN_INSTALL:-0}" == 1 ]]; then
    cp "$RUN/mgmot-det-fp32.onnx" "$RUN/mgmot-det-int8.onnx" "$ROOT/models/"
    cp "$RUN/metrics.json" "$ROOT/models/metrics.json"
    echo "installed into $ROOT/models (update models/README.md with metrics.json)"
fi
echo "done: $RUN"
