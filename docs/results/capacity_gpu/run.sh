#!/bin/bash
# Issue 32 item 3: the capacity study on a lent GPU (docs/results/capacity_gpu.md). Run from the repository root:
#   bash docs/results/capacity_gpu/run.sh          (on the GPU machine; OUT= a folder for the checkpoints)
# It needs torch, numpy, scipy, h5py and trimesh (a trimesh wheel in $WHEELS, default .gpu/, is installed when
# trimesh is missing); open3d and casadi are not needed (the numpy renderer, no pose validation).
# FRAMES / TLIM (minutes per training) / DEVICE / WORKERS / PY are overridable for a dry run on a CPU:
#   FRAMES=64 TLIM=0.3 DEVICE=cpu WORKERS=2 PY=.venv/bin/python bash docs/results/capacity_gpu/run.sh
set -u
HERE=$(cd "$(dirname "$0")" && pwd)
export PYTHONUNBUFFERED=1
FRAMES=${FRAMES:-6000}; TLIM=${TLIM:-5}; DEVICE=${DEVICE:-cuda}; WORKERS=${WORKERS:-16}; PY=${PY:-python3}
OUT=${OUT:-/tmp/gpu_out}; mkdir -p "$OUT"; LOGS=/tmp/gpu_logs; rm -rf $LOGS /tmp/gpu_lt /tmp/gpu_runs; mkdir -p $LOGS
. "$HERE/../gpu_preamble.sh"  # stamp(), trimesh, PYTHONPATH, the machine in the timeline
timeout 120 $PY $HERE/check.py $DEVICE > $LOGS/gpu_check.txt 2>&1; stamp "gpu check rc $? $(tail -1 $LOGS/gpu_check.txt)"
timeout 170 $PY -m ancsh.cli data generate --category laptop --split train --frames $FRAMES --workers $WORKERS \
  --shard-size $(( (FRAMES + WORKERS - 1) / WORKERS )) --seed 40 --out /tmp/gpu_lt --quiet > $LOGS/generate.txt 2>&1
stamp "generate rc $? $(tail -1 $LOGS/generate.txt)"
for cfg in w05 w10ref w10ref2; do
  timeout $(python3 -c "print(int($TLIM * 60 + 100))") $PY -m ancsh.cli train --category laptop --config $HERE/$cfg.json \
    --data /tmp/gpu_lt --out /tmp/gpu_runs/$cfg --device $DEVICE --time-limit-min $TLIM --no-progress > $LOGS/train_$cfg.txt 2>&1 &
done
wait
stamp "trainings done"
for cfg in w05 w10ref w10ref2; do
  d=/tmp/gpu_runs/$cfg; cp $d/history.csv $LOGS/history_$cfg.csv 2>/dev/null
  for k in best last; do [ -f $d/$k.pt ] && $PY $HERE/strip.py $d/$k.pt $OUT/${cfg}_$k.pt >> $LOGS/timeline.txt 2>&1; done
done
nvidia-smi > $LOGS/nvidia_smi.txt 2>&1
stamp "end"
tar czf $OUT/logs.tar.gz -C /tmp gpu_logs
ls -la $OUT
