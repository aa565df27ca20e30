#!/usr/bin/env bash
# BoxMOT 25.0.0 (BoT-SORT, ByteTrack, OC-SORT; each with the paper's thresholds and with
# BoxMOT's own) against mgmot (online, online with provisional tracks withheld, offline) on
# the same simulated detections, all scored by `mgmot eval`. Not part of CI: BoxMOT pulls
# PyTorch, about 6 GB in a virtual environment of its own.
#
#   scripts/compare_boxmot.sh                       # every scenario x 4 seeds
#   scripts/compare_boxmot.sh --scenarios swimmer_group --seeds "7771 90210"
#
# --venv DIR: the environment with boxmot (default out/boxmot-venv; created, and boxmot
#   installed from PyPI, when it cannot import boxmot).
# --frames-scenarios LIST: scenarios whose frames are rendered (`mgmot-sim render`, about
#   real time on one core) so that BoT-SORT compensates camera motion (sparse optical flow);
#   default the short ones. The long missions (8-15 min) run without frames: BoT-SORT
#   without camera-motion compensation there.
# Prints a Markdown table; the runs are kept in --out (default out/compare_boxmot).
set -euo pipefail
cd "$(dirname "$0")/.."

scenarios="leave_and_return swimmer_group gimbal_swings boats_crossing calm_baseline fast_drone mixed_mission_soak lawnmower_search expanding_square sector_search"
frames_scenarios="leave_and_return swimmer_group gimbal_swings boats_crossing calm_baseline fast_drone"
seeds="default 7771 90210 31337"
out=out/compare_boxmot
venv=out/boxmot-venv
while [ $# -gt 0 ]; do
  case "$1" in
    --scenarios) scenarios="$2"; shift 2 ;;
    --frames-scenarios) frames_scenarios="$2"; shift 2 ;;
    --seeds) seeds="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --venv) venv="$2"; shift 2 ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    *) echo "compare_boxmot: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done

if ! "$venv/bin/python" -c 'import boxmot' 2>/dev/null; then
  echo "compare_boxmot: installing boxmot 25.0.0 into $venv (PyTorch: about 6 GB)" >&2
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet boxmot==25.0.0
fi
if [ -n "${MGMOT_BIN:-}" ]; then
  bin="$MGMOT_BIN"
else
  cargo build --release --quiet -p mgmot -p mgmot-sim
  bin=target/release
fi

n=0; total=$(( $(wc -w <<<"$scenarios") * $(wc -w <<<"$seeds") ))
for sc in $scenarios; do
  for seed in $seeds; do
    n=$((n + 1))
    dir="$out/$sc/$seed"
    rm -rf "$dir"; mkdir -p "$dir"
    seed_flag=()
    [ "$seed" = default ] || seed_flag=(--seed "$seed")
    frames=()
    if [[ " $frames_scenarios " == *" $sc "* ]]; then
      echo "[$n/$total] $sc seed $seed: render frames" >&2
      "$bin/mgmot-sim" render --scenario "$sc" "${seed_flag[@]}" --format jpg --out "$dir/render" >/dev/null 2>&1
      frames=("$dir/render/img1"); touch "$dir/with_frames"
    fi
    echo "[$n/$total] $sc seed $seed: track" >&2
    # With colour signatures, as scripts/bench_tracking.sh simulates them (mgmot uses them;
    # BoxMOT reads the boxes only, which are the same with or without).
    "$bin/mgmot-sim" detections --scenario "$sc" "${seed_flag[@]}" --appearance --out "$dir/det.txt" --gt-dir "$dir/gt" >/dev/null 2>&1
    gt="$dir/gt/gt/gt.txt"
    for run in online online_withheld offline; do
      case $run in
        online) flags=(--mode online) ;;
        online_withheld) flags=(--mode online --withhold-provisional) ;;
        offline) flags=(--mode offline) ;;
      esac
      "$bin/mgmot" track --annotations "$dir/gt/annotations.json" --detections "$dir/det.txt" "${flags[@]}" --json --out "$dir/$run" >/dev/null
      mv "$(ls "$dir/$run"/*.txt)" "$dir/$run.txt"
      "$bin/mgmot" eval --gt "$gt" --pred "$dir/$run.txt" --json > "$dir/$run.json"
    done
    for tracker in botsort bytetrack ocsort; do
      for conf in paper default; do
        f=()
        [ "$tracker" = botsort ] && f=("${frames[@]}")
        "$venv/bin/python" scripts/compare_boxmot.py track "$tracker" "$conf" "$dir/det.txt" \
          "$dir/gt/seqinfo.ini" "$dir/boxmot_${tracker}_$conf.txt" "${f[@]}" 2>>"$dir/boxmot.log" >/dev/null
        "$bin/mgmot" eval --gt "$gt" --pred "$dir/boxmot_${tracker}_$conf.txt" --json > "$dir/boxmot_${tracker}_$conf.json"
      done
    done
    rm -rf "$dir/render"
  done
done
"$venv/bin/python" scripts/compare_boxmot.py table "$out"
