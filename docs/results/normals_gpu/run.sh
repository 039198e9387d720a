#!/bin/bash
# Issue 32: normals first stages for the categories that miss their targets, trained on a lent GPU (prepared
# 2026-12-05 after levers_gpu.md's call 3; not run yet). Run from the repository root on the GPU machine:
#   bash docs/results/normals_gpu/run.sh          (OUT= a folder for the checkpoints; carry .gpu/ with the trimesh wheel)
# Per category of CATEGORIES: 6000 new training frames (seed SEED_<category>, all categories' generations side by side,
# WORKERS split between them), then SEEDS trainings of normals.json (the shipped layout with input normals, from
# scratch, lr 1e-3 x0.7 every 2000 steps) side by side on the one GPU, each to STEPS steps or TLIM minutes. Back come
# best.pt (lowest validation loss; no casadi there) and last.pt of each, and the histories. Then, on the CPU: `ancsh
# export` ranks them on their validation frames (the data regenerated with the same seed and shard size), the chosen
# one is fine-tuned with the pose-aware loss (as the laptop's in levers_gpu.md) and evaluated beside the shipped first
# stage. Budget: 3 categories x 2 seeds fit one 10-minute call (generation ~2.5 min, 6 trainings ~6 min at ~0.035 s
# per step side by side on an H100).
# A dry run on a CPU: CATEGORIES="oven" SEEDS="41" FRAMES=32 STEPS=4 TLIM=0.3 DEVICE=cpu WORKERS=1 PY=.venv/bin/python bash ...
set -u
HERE=$(cd "$(dirname "$0")" && pwd)
export PYTHONUNBUFFERED=1
CATEGORIES=${CATEGORIES:-"oven washing_machine drawer"}; SEEDS=${SEEDS:-"41 42"}
FRAMES=${FRAMES:-6000}; STEPS=${STEPS:-12000}; TLIM=${TLIM:-6}; DEVICE=${DEVICE:-cuda}; WORKERS=${WORKERS:-15}; PY=${PY:-python3}
OUT=${OUT:-/tmp/gpu_out}; mkdir -p "$OUT"; LOGS=/tmp/gpu_logs; rm -rf $LOGS /tmp/gpu_data /tmp/gpu_runs /tmp/gpu_last
mkdir -p $LOGS /tmp/gpu_last
. "$HERE/../gpu_preamble.sh"  # stamp(), trimesh, PYTHONPATH, the machine in the timeline
n=$(echo $CATEGORIES | wc -w); w=$(( WORKERS / n > 0 ? WORKERS / n : 1 ))
for cat in $CATEGORIES; do
  seed=$($PY -c "import json; print(json.load(open('$HERE/seeds.json'))['$cat'])")
  timeout 200 $PY -m ancsh.cli data generate --category $cat --split train --frames $FRAMES --workers $w \
    --shard-size $(( (FRAMES + w - 1) / w )) --seed $seed --out /tmp/gpu_data/$cat --quiet > $LOGS/generate_$cat.txt 2>&1 &
done
wait
for cat in $CATEGORIES; do stamp "generate $cat: $(tail -1 $LOGS/generate_$cat.txt)"; done
for cat in $CATEGORIES; do
  for s in $SEEDS; do
    $PY -c "import json; c = json.load(open('$HERE/normals.json')); c.update(category='$cat', seed=$s, max_steps=$STEPS); json.dump(c, open('/tmp/gpu_logs/${cat}_s$s.json', 'w'), indent=1)"
    timeout $(python3 -c "print(int($TLIM * 60 + 100))") $PY -m ancsh.cli train --category $cat --config $LOGS/${cat}_s$s.json \
      --data /tmp/gpu_data/$cat --out /tmp/gpu_runs/${cat}_s$s --device $DEVICE --time-limit-min $TLIM --no-progress > $LOGS/train_${cat}_s$s.txt 2>&1 &
  done
done
wait
stamp "trainings done"
for cat in $CATEGORIES; do
  for s in $SEEDS; do
    d=/tmp/gpu_runs/${cat}_s$s; cp $d/history.csv $LOGS/history_${cat}_s$s.csv 2>/dev/null
    [ -f $d/best.pt ] && $PY $HERE/../capacity_gpu/strip.py $d/best.pt $OUT/${cat}_s${s}_best.pt >> $LOGS/timeline.txt 2>&1
    [ -f $d/last.pt ] && $PY $HERE/../capacity_gpu/strip.py $d/last.pt /tmp/gpu_last/${cat}_s${s}_last.pt >> $LOGS/timeline.txt 2>&1
  done
done
stamp "end"
tar czf $OUT/logs.tar.gz -C /tmp gpu_logs
tar cf $OUT/last.tar -C /tmp gpu_last
ls -la $OUT
