#!/bin/bash
# Issue 32 item 2: the levers at equal compute on a lent GPU (docs/results/levers_gpu.md). Run from the repository root:
#   bash docs/results/levers_gpu/run.sh          (on the GPU machine; OUT= a folder for the checkpoints)
# The set-up of docs/results/capacity_gpu/run.sh (the same data, seed, schedule and 5 minutes per training, so its rows
# join this table): 6000 laptop frames, then six trainings side by side on the one GPU, each a lever on the shipped
# layout (width 0.5): none, normals, roll augmentation 30 deg, pose loss 0.1, pose loss 1, all three together.
# It needs torch, numpy, scipy, h5py and trimesh (a trimesh wheel in $WHEELS, default .gpu/, is installed when
# trimesh is missing); open3d and casadi are not needed (the numpy renderer, no pose validation).
# FRAMES / TLIM (minutes per training) / DEVICE / WORKERS / PY are overridable for a dry run on a CPU:
#   FRAMES=64 TLIM=0.3 DEVICE=cpu WORKERS=1 PY=.venv/bin/python bash docs/results/levers_gpu/run.sh
# RUNS names the configurations (<run>.json beside this script); the replicates of the second call:
#   RUNS="base_s41 base_s42 base_s43 pose1_s41 pose1_s42 pose1_s43" TLIM=2.25 bash docs/results/levers_gpu/run.sh
# the third call (equal CPU time: each configuration's max_steps; TLIM only a cap):
#   RUNS="base_long_s41 base_long_s42 base_long_s43 normals_long_s41 normals_long_s42 normals_long_s43" TLIM=6.3 bash ...
# CATEGORY (default laptop) runs the same on another category's frames (it overrides the configurations' category).
set -u
HERE=$(cd "$(dirname "$0")" && pwd)
export PYTHONUNBUFFERED=1
CATEGORY=${CATEGORY:-laptop}; FRAMES=${FRAMES:-6000}; TLIM=${TLIM:-5}; DEVICE=${DEVICE:-cuda}; WORKERS=${WORKERS:-16}; PY=${PY:-python3}
RUNS=${RUNS:-"base normals roll30 pose01 pose1 all"}
OUT=${OUT:-/tmp/gpu_out}; mkdir -p "$OUT"; LOGS=/tmp/gpu_logs; rm -rf $LOGS /tmp/gpu_lt /tmp/gpu_runs /tmp/gpu_last; mkdir -p $LOGS /tmp/gpu_last
. "$HERE/../gpu_preamble.sh"  # stamp(), trimesh, PYTHONPATH, the machine in the timeline
timeout 170 $PY -m ancsh.cli data generate --category $CATEGORY --split train --frames $FRAMES --workers $WORKERS \
  --shard-size $(( (FRAMES + WORKERS - 1) / WORKERS )) --seed 40 --out /tmp/gpu_lt --quiet > $LOGS/generate.txt 2>&1
stamp "generate rc $? $(tail -1 $LOGS/generate.txt)"
for cfg in $RUNS; do
  timeout $(python3 -c "print(int($TLIM * 60 + 100))") $PY -m ancsh.cli train --category $CATEGORY --config $HERE/$cfg.json \
    --data /tmp/gpu_lt --out /tmp/gpu_runs/$cfg --device $DEVICE --time-limit-min $TLIM --no-progress > $LOGS/train_$cfg.txt 2>&1 &
done
wait
stamp "trainings done"
for cfg in $RUNS; do
  d=/tmp/gpu_runs/$cfg; cp $d/history.csv $LOGS/history_$cfg.csv 2>/dev/null
  [ -f $d/best.pt ] && $PY $HERE/../capacity_gpu/strip.py $d/best.pt $OUT/${cfg}_best.pt >> $LOGS/timeline.txt 2>&1
  [ -f $d/last.pt ] && $PY $HERE/../capacity_gpu/strip.py $d/last.pt /tmp/gpu_last/${cfg}_last.pt >> $LOGS/timeline.txt 2>&1
done
nvidia-smi > $LOGS/nvidia_smi.txt 2>&1
stamp "end"
tar czf $OUT/logs.tar.gz -C /tmp gpu_logs
tar cf $OUT/last.tar -C /tmp gpu_last
ls -la $OUT
