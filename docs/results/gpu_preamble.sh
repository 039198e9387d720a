# Sourced by the prepared GPU scripts (docs/results/capacity_gpu/run.sh, docs/results/levers_gpu/run.sh) after they set
# PY and LOGS: the timeline's stamp(), trimesh from a wheel where the machine lacks it ($WHEELS, default .gpu/), the
# repository on PYTHONPATH, and the machine's first lines in the timeline.
t0=$(date +%s); stamp() { echo "[$(( $(date +%s) - t0 )) s] $*" | tee -a $LOGS/timeline.txt; }
if ! $PY -c "import trimesh" 2>/dev/null; then
  $PY -m pip install -q --no-index --no-deps --no-compile --target /tmp/site ${WHEELS:-.gpu}/trimesh-*.whl && export PYTHONPATH=/tmp/site
fi
export PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}$PWD
stamp "start; $(nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>/dev/null); nproc $(nproc)"
$PY -c "import torch, numpy, scipy, h5py, trimesh; print('torch', torch.__version__, 'cuda', torch.cuda.is_available(), 'numpy', numpy.__version__, 'scipy', scipy.__version__)" 2>&1 | tee -a $LOGS/timeline.txt
