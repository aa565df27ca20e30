#!/usr/bin/env bash
# One command from nothing to the shipped models (see train/README.md):
#
#   train/run.sh                       # render, train, export, quantise, evaluate
#   MGMOT_TRAIN_INSTALL=1 train/run.sh # ... and copy the models + metrics into models/
#   MGMOT_TRAIN_DATA=/data/seadronessee train/run.sh
#                                      # real footage in the SeaDronesSee layout instead of renders
#
# Environment knobs (defaults in brackets):
#   MGMOT_TRAIN_MINUTES  wall-clock training budget, stage 1         [40]
#   MGMOT_TRAIN_FT_MINUTES  class-balanced fine-tune, stage 2        [15]
#   MGMOT_TRAIN_SCALE_MINUTES  fine-tune at the runtime's scale, stage 3 [45]
#   MGMOT_TRAIN_MORE_MINUTES  the same on twice the frames, stage 4    [50]
#   MGMOT_TRAIN_STAGE6_MINUTES  stage 4 again on three times the frames, stage 6 [50]
#   MGMOT_TRAIN_RESUME   1 = keep an existing stage-1 checkpoint       [0]
#   MGMOT_TRAIN_FRAMES   minimum training frames to render          [5000]
#   MGMOT_TRAIN_EXTRA_FRAMES  minimum frames of further training seeds, for stage 4 [5000]
#   MGMOT_TRAIN_EXTRA2_FRAMES  minimum frames of the seeds after those, for stage 6 [5000]
#   MGMOT_TRAIN_PER_SEQ  frames kept per rendered sequence           [40]
#   MGMOT_TRAIN_THREADS  torch threads                               [1]
#   MGMOT_TRAIN_INIT_REV the commit whose models/mgmot-det-fp32.onnx starts training, or none [8817652]
#   MGMOT_TRAIN_INSTALL  1 = copy models + metrics into models/     [0]
#   MGMOT_TRAIN_DATA     a SeaDronesSee-layout dataset (images/{train,val}/, annotations/instances_{train,val}.json):
#                        train on its train split, evaluate on its val split; nothing is rendered
#   MGMOT_SIM            a prebuilt mgmot-sim binary  [built: target/release/mgmot-sim]
#   MGMOT_TRAIN_TILE_MINUTES  the tile model's fine-tune, stage 5 (renders only; 0: none) [30]
#   MGMOT_TRAIN_TILE_SEEDS  training seeds rendered again as lossless PNG for stage 5 [20]
#   MGMOT_TRAIN_STOP     stop after this step: data | train          [run all]
# Seeds and splits (renders): training uses seeds 1, 2, ... (every scenario per seed) until
# MGMOT_TRAIN_FRAMES frames exist (train/), then the next seeds until MGMOT_TRAIN_EXTRA_FRAMES
# more exist (train-extra/, stages 4 and 6; seeds 13-24 at the defaults), then the next seeds
# until MGMOT_TRAIN_EXTRA2_FRAMES more exist (train-extra2/, stage 6 only; seeds 25-36); tuning seeds 50001 and 50002 (training conditions, for
# choosing between recipes); held-out seeds 100001 and 100002 (same conditions as
# training, disjoint seeds); held-out conditions: seeds 200001-200003, each variant drawn from
# one condition training never saw (rough sea, low sun, the 80-100 m altitude band; see
# scenarios.py). torch / numpy are seeded with 1. A manifest of every rendered sequence and
# its parameters is written to runs/sim/manifest.json.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/.." && pwd)"
MINUTES="${MGMOT_TRAIN_MINUTES:-40}"
FT_MINUTES="${MGMOT_TRAIN_FT_MINUTES:-15}"
SCALE_MINUTES="${MGMOT_TRAIN_SCALE_MINUTES:-45}"
MORE_MINUTES="${MGMOT_TRAIN_MORE_MINUTES:-50}"
TILE_MINUTES="${MGMOT_TRAIN_TILE_MINUTES:-30}"
TILE_SEEDS="${MGMOT_TRAIN_TILE_SEEDS:-20}"
FRAMES="${MGMOT_TRAIN_FRAMES:-5000}"
EXTRA_FRAMES="${MGMOT_TRAIN_EXTRA_FRAMES:-5000}"
EXTRA2_FRAMES="${MGMOT_TRAIN_EXTRA2_FRAMES:-5000}"
STAGE6_MINUTES="${MGMOT_TRAIN_STAGE6_MINUTES:-50}"
PER_SEQ="${MGMOT_TRAIN_PER_SEQ:-40}"
RUN="$HERE/runs/sim"
DATA="$HERE/data/sim"
SCENARIOS=(calm_baseline high_altitude_tiny swimmer_group boats_crossing fast_drone gimbal_swings
    leave_and_return mixed_mission_soak camera_desync gimbal_pitch_bias telemetry_dropout)
mkdir -p "$RUN" "$DATA/scenarios"

# 1. Python environment (pinned).
if [[ ! -x "$HERE/.venv/bin/python" ]]; then
    python3 -m venv "$HERE/.venv"
    "$HERE/.venv/bin/pip" install --quiet -r "$HERE/requirements.txt"
fi
PY="$HERE/.venv/bin/python"
cd "$HERE"

PY_THREADS="${MGMOT_TRAIN_THREADS:-1}"
EVAL=()
if [[ -n "${MGMOT_TRAIN_DATA:-}" ]]; then
    # 2'. Real footage in the SeaDronesSee layout: nothing to render, and no tile model (stage 5
    #     is for renders' lossless frames; real footage shows the model its own camera's pixels).
    TILE_MINUTES=0
    "$PY" -c "import data, sys; s = data.load_seadronessee(sys.argv[1], 'train'); print(f'{len(s)} training frames in', sys.argv[1])" "$MGMOT_TRAIN_DATA"
    TRAIN_DATA="$MGMOT_TRAIN_DATA"
    MORE_DATA=()
    MORE2_DATA=()
    EVAL=("val:$MGMOT_TRAIN_DATA")
else
    # 2. Data: JPEG sequences rendered by mgmot-sim (1280x720, SeaDronesSee-style JSON).
    SIM="${MGMOT_SIM:-}"
    if [[ -z "$SIM" ]]; then
        (cd "$ROOT" && cargo build --release -p mgmot-sim)
        SIM="$ROOT/target/release/mgmot-sim"
    fi
    count_frames() { find "$1" \( -name '*.jpg' -o -name '*.png' \) 2>/dev/null | wc -l; }
    render() { # split scenario seed
        local out="$DATA/$1/${2}_s$3"
        [[ -f "$out/annotations.json" ]] && return 0
        local toml="$DATA/scenarios/${2}_s$3.toml" every variant=$1 format=jpg
        # tuning seeds and further training seeds: variants of the training conditions
        [[ $1 == tuning || $1 == train-extra || $1 == train-extra2 ]] && variant=train
        # the held-out seeds again, as lossless PNG (what an uncompressed camera delivers)
        [[ $1 == heldout-lossless ]] && variant=heldout format=png
        # and the tuning seeds, to choose recipes for uncompressed frames
        [[ $1 == tuning-lossless ]] && variant=train format=png
        # and the training seeds, for the tile model (stage 5)
        [[ $1 == train-lossless ]] && variant=train format=png
        every="$("$PY" scenarios.py --sim-dir "$ROOT/sim/scenarios" --name "$2" --seed "$3" --split "$variant" --out "$toml" --frames "$PER_SEQ")"
        rm -rf "$out"
        "$SIM" render -s "$toml" -o "$out" --format "$format" --every "$every" 2>/dev/null
    }
    render_until() { # split min_frames first_seed: every scenario per seed until the split has min_frames
        local seed=$3
        while (( $(count_frames "$DATA/$1") < $2 )); do
            for sc in "${SCENARIOS[@]}"; do render "$1" "$sc" "$seed"; done
            echo "rendered $1 seed $seed: $(count_frames "$DATA/$1") frames"
            seed=$((seed + 1))
        done
    }
    last_seed() { # the largest seed rendered into split $1 (0 when none)
        local max=0 d s
        for d in "$DATA/$1"/*_s*; do
            [[ -d $d ]] || continue
            s=${d##*_s}
            (( s > max )) && max=$s
        done
        echo "$max"
    }
    render_until train "$FRAMES" 1
    # The further seeds follow the training ones, also when train/ was complete before this run.
    render_until train-extra "$EXTRA_FRAMES" $(( $(last_seed train) + 1 ))
    render_until train-extra2 "$EXTRA2_FRAMES" $(( $(last_seed train-extra) + 1 ))
    if (( TILE_MINUTES > 0 )); then
        for seed in $(seq 1 "$TILE_SEEDS"); do
            for sc in "${SCENARIOS[@]}"; do render train-lossless "$sc" "$seed"; done
        done
        echo "rendered train-lossless seeds 1-$TILE_SEEDS: $(count_frames "$DATA/train-lossless") frames"
    fi
    for sc in "${SCENARIOS[@]}"; do
        for seed in 100001 100002; do render heldout "$sc" "$seed"; render heldout-lossless "$sc" "$seed"; done
        for seed in 200001 200002 200003; do render conditions "$sc" "$seed"; done
        # Tuning seeds (training conditions, seeds disjoint from both): choosing between
        # training recipes is done on these, so that the held-out figures stay unseen.
        for seed in 50001 50002; do render tuning "$sc" "$seed"; render tuning-lossless "$sc" "$seed"; done
    done
    echo "frames: train $(count_frames "$DATA/train"), further training $(count_frames "$DATA/train-extra") and $(count_frames "$DATA/train-extra2"), tuning $(count_frames "$DATA/tuning"), held-out seeds $(count_frames "$DATA/heldout"), held-out conditions $(count_frames "$DATA/conditions")"
    "$PY" scenarios.py manifest --data "$DATA" --out "$RUN/manifest.json"
    TRAIN_DATA="$DATA/train"
    MORE_DATA=("$DATA/train-extra")
    MORE2_DATA=("$DATA/train-extra" "$DATA/train-extra2")
    EVAL=("tuning:$DATA/tuning" "tuning-lossless:$DATA/tuning-lossless" "heldout:$DATA/heldout"
        "conditions:$DATA/conditions" "heldout-lossless:$DATA/heldout-lossless")
fi
[[ "${MGMOT_TRAIN_STOP:-}" == data ]] && exit 0

# 3. Train (time-bounded), warm-started from the two-class model shipped at INIT_REV (taken from
#    git, so the start is the same on every machine; MGMOT_TRAIN_INIT_REV=none: from scratch).
INIT_REV="${MGMOT_TRAIN_INIT_REV:-8817652}"
INIT=()
if [[ "$INIT_REV" != none ]]; then
    git -C "$ROOT" show "$INIT_REV:models/mgmot-det-fp32.onnx" > "$RUN/init.onnx"
    INIT=(--init-onnx "$RUN/init.onnx")
fi
if [[ "${MGMOT_TRAIN_RESUME:-0}" == 1 && -f "$RUN/tinydet-stage1.pt" ]]; then
    echo "stage 1: kept $RUN/tinydet-stage1.pt (MGMOT_TRAIN_RESUME=1)"
else
    "$PY" train.py --data "$TRAIN_DATA" --crop 192 --batch 16 --threads "$PY_THREADS" --minutes "$MINUTES" --seed 1 \
        "${INIT[@]}" --out "$RUN/tinydet-stage1.pt"
fi
# 3b. Class-balanced fine-tune: frames and views drawn by class weight (commonest / class)^0.5,
#     so jetskis, life-saving appliances and buoys are seen about as often as swimmers.
"$PY" train.py --data "$TRAIN_DATA" --crop 192 --batch 16 --threads "$PY_THREADS" --minutes "$FT_MINUTES" --seed 2 \
    --lr 1e-3 --balance 0.5 --init "$RUN/tinydet-stage1.pt" --out "$RUN/tinydet-stage2.pt"
# 3c. At the runtime's scale: stages 1 and 2 scale frames by 0.2-1 and letterbox 10 % of them
#     whole into the 192 px crop (0.15), but `mgmot run` letterboxes a 1280x720 frame into the
#     800x448 input (0.62) or, tiled, reads native pixels (1). Views scaled by 0.45-1 only, no
#     whole-frame views, a little more class balance.
"$PY" train.py --data "$TRAIN_DATA" --crop 192 --batch 16 --threads "$PY_THREADS" --minutes "$SCALE_MINUTES" --seed 3 \
    --lr 1e-3 --balance 0.6 --scales 0.45,1.0 --whole-frame 0 --init "$RUN/tinydet-stage2.pt" --out "$RUN/tinydet-stage3.pt"
# 3d. Stage 3's recipe again at half its learning rate, on the training frames plus as many
#     again from further seeds (renders; a real dataset's train split alone).
"$PY" train.py --data "$TRAIN_DATA" "${MORE_DATA[@]}" --crop 192 --batch 16 --threads "$PY_THREADS" --minutes "$MORE_MINUTES" \
    --seed 4 --lr 5e-4 --balance 0.6 --scales 0.45,1.0 --whole-frame 0 --init "$RUN/tinydet-stage3.pt" --out "$RUN/tinydet-stage4.pt"
"$PY" export.py --ckpt "$RUN/tinydet-stage4.pt" --size 448,800 --out "$RUN/stage4-fp32.onnx" \
    --description "mgmot TinyDet five-class SeaDronesSee detector, trained on mgmot-sim frames"
# 3e. Stage 4's recipe once more, warm-started from its export, on three times the frames
#     (seeds 1-36; a real dataset's train split alone), at 3e-4 (models/README.md, "What it was
#     trained on", item 6; the shipped run had two torch threads).
"$PY" train.py --data "$TRAIN_DATA" "${MORE2_DATA[@]}" --crop 192 --batch 16 --threads "$PY_THREADS" \
    --minutes "$STAGE6_MINUTES" --seed 8 --lr 3e-4 --balance 0.6 --scales 0.45,1.0 --whole-frame 0 \
    --init-onnx "$RUN/stage4-fp32.onnx" --out "$RUN/tinydet.pt"
[[ "${MGMOT_TRAIN_STOP:-}" == train ]] && exit 0
"$PY" export.py --ckpt "$RUN/tinydet.pt" --size 448,800 --out "$RUN/mgmot-det-fp32.onnx" \
    --description "mgmot TinyDet five-class SeaDronesSee detector, trained on mgmot-sim frames"
# int8: static QDQ calibrated on 320 training frames, the count at which tract and ONNX Runtime
# agree exactly on the parity test's fixtures (models/README.md, "Backend parity").
"$PY" quantize.py --fp32 "$RUN/mgmot-det-fp32.onnx" --out "$RUN/mgmot-det-int8.onnx" --data "$TRAIN_DATA" --count 320
# 5. The tile model (renders only): stage 6's model fine-tuned on the training seeds rendered again as
#    lossless PNG, half the frames JPEG-compressed before scaling and 30 % of the views at scale
#    1, what a tile of an uncompressed camera's frame shows. `mgmot run` runs it on the frames it
#    tiles (`[detector] tile_model`); models/README.md, "The tile model". Its int8 model is
#    calibrated on 320 frames, the count at which tract and ONNX Runtime agree on the test's
#    fixtures (whole and tiled).
if (( TILE_MINUTES > 0 )); then
    "$PY" train.py --data "$DATA/train-lossless" --crop 192 --batch 16 --threads "$PY_THREADS" --minutes "$TILE_MINUTES" \
        --seed 6 --lr 1.5e-4 --balance 0.6 --scales 0.45,1.0 --whole-frame 0 --jpeg 0.5,60,95 --native 0.3 \
        --init-onnx "$RUN/mgmot-det-fp32.onnx" --out "$RUN/tinydet-tiles.pt"
    "$PY" export.py --ckpt "$RUN/tinydet-tiles.pt" --size 448,800 --out "$RUN/mgmot-det-tiles-fp32.onnx" \
        --description "mgmot TinyDet five-class SeaDronesSee tile model, trained on mgmot-sim frames, lossless and JPEG"
    "$PY" quantize.py --fp32 "$RUN/mgmot-det-tiles-fp32.onnx" --out "$RUN/mgmot-det-tiles-int8.onnx" \
        --data "$DATA/train-lossless" --count 320
fi
for e in "${EVAL[@]}"; do
    name="${e%%:*}" dir="${e#*:}"
    "$PY" evaluate.py --models "$RUN/mgmot-det-fp32.onnx" "$RUN/mgmot-det-int8.onnx" --data "$dir" --split val \
        --count 600 --modes full,tiled --tiled-every 1 --threads "$PY_THREADS" --json "$RUN/metrics-$name.json" \
        | tee "$RUN/metrics-$name.txt"
    if (( TILE_MINUTES > 0 )); then
        "$PY" evaluate.py --models "$RUN/mgmot-det-tiles-fp32.onnx" "$RUN/mgmot-det-tiles-int8.onnx" --data "$dir" \
            --split val --count 600 --modes full,tiled --tiled-every 1 --threads "$PY_THREADS" \
            --json "$RUN/metrics-tiles-$name.json" | tee "$RUN/metrics-tiles-$name.txt"
    fi
done
"$PY" -c "
import json, sys
run = sys.argv[1]
names = sys.argv[2:]
import os
out = {n: json.load(open(f'{run}/metrics-{n}.json')) for n in names}
tiles = {n: json.load(open(f'{run}/metrics-tiles-{n}.json')) for n in names if os.path.exists(f'{run}/metrics-tiles-{n}.json')}
if tiles:
    out['tile_model'] = tiles
json.dump(out, open(f'{run}/metrics.json', 'w'), indent=2)
" "$RUN" "${EVAL[@]%%:*}"

if [[ "${MGMOT_TRAIN_INSTALL:-0}" == 1 ]]; then
    cp "$RUN/mgmot-det-fp32.onnx" "$RUN/mgmot-det-int8.onnx" "$ROOT/models/"
    # the tile model ships int8 only: tiling is affordable on ONNX Runtime int8 (models/README.md)
    if (( TILE_MINUTES > 0 )); then cp "$RUN/mgmot-det-tiles-int8.onnx" "$ROOT/models/"; fi
    cp "$RUN/metrics.json" "$ROOT/models/metrics.json"
    "$PY" -c "
import json, sys
run = sys.argv[1]
import os
stages = {f'stage{i}': json.load(open(f'{run}/{n}.log.json')) for i, n in ((1, 'tinydet-stage1'), (2, 'tinydet-stage2'), (3, 'tinydet-stage3'), (4, 'tinydet-stage4'), (5, 'tinydet-tiles'), (6, 'tinydet')) if i != 5 or os.path.exists(f'{run}/{n}.log.json')}
json.dump(stages, open(sys.argv[2], 'w'), indent=1)
" "$RUN" "$ROOT/models/training-log.json"
    [[ -f "$RUN/manifest.json" ]] && cp "$RUN/manifest.json" "$ROOT/models/data-manifest.json"
    echo "installed into $ROOT/models (update models/README.md with metrics.json)"
fi
echo "done: $RUN"
