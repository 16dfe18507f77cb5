#!/usr/bin/env bash
# Issue 37's batched live tracker on a GPU machine, in one device call (about 9 minutes with 16 cores):
# three-device walkers tracked in the receiver (one `Crowd` thread, one batched forward pass of the
# shipped Suite-IN++ per tick for every session), with the models on the GPU (`--model-device cuda`)
# and then on the same machine's CPU (`--model-device cpu`): what the host pays for a crowd's small
# batches on each. `trackers` as a third argument adds 12 `wearnav live track` processes (models on
# the GPU) as a last step (about 4 minutes more).
#
#   scripts/gpu_live.sh OUT [quick|full] [trackers]
#
# OUT gets log.txt, nvidia-smi's utilisation each second (gpu.csv) and one page per step
# (in-process-cuda/, in-process-cpu/, trackers/: results.md and results.json). `quick` shrinks every
# step so that the script can be checked on a CPU-only machine in a few minutes (the cuda step is
# then skipped). Each step has its own time limit: a step cut short writes no page, only its log lines.
# A machine without wearnav's dependencies (a lent one had torch but not shapely, pymap3d, starlette or
# uvicorn) takes them as wheels for its Python on PYTHONPATH, e.g. `pip install --target build/devdeps
# --only-binary=:all: --python-version 3.12 --platform manylinux2014_x86_64 pymap3d shapely starlette uvicorn`.
set -u
out=${1:?usage: scripts/gpu_live.sh OUT [quick|full] [trackers]}
quick=${2:-}
[ "$quick" = full ] && quick=
with_trackers=${3:-}
mkdir -p "$out"
export PYTHONUNBUFFERED=1 PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}src
py=${PYTHON:-python3}
step() { echo "== $(date -u +%T) $*"; }

if [ -n "$quick" ]; then
    w_in=2 w_tr=2 trackers=1 cpu_s=4 dur=3 on=cpu
else
    w_in=8,16 w_tr=16,32 trackers=12 cpu_s=20 dur=5 on="cuda cpu"
fi
{
    step machine
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1 || true
    nproc
    "$py" -c 'import torch; print("torch", torch.__version__, "cuda", torch.cuda.is_available())'
    if command -v nvidia-smi >/dev/null; then
        nvidia-smi --query-gpu=timestamp,utilization.gpu,memory.used --format=csv -l 1 >"$out/gpu.csv" 2>&1 &
        smi=$!
    fi

    for dev in $on; do
        step "three-device walkers, tracked in the receiver, models on $dev"
        timeout 250 "$py" -m wearnav live bench --walkers "$w_in" --devices all --cpu-s "$cpu_s" --duration "$dur" \
            --model-device "$dev" --out "$out/in-process-$dev"
    done
    if [ -n "$with_trackers" ]; then
        step "three-device walkers, $trackers tracker processes"
        timeout 270 "$py" -m wearnav live bench --walkers "$w_tr" --devices all --trackers "$trackers" \
            --cpu-s "$cpu_s" --duration "$dur" --model-device "${on%% *}" --out "$out/trackers"
    fi
    [ -n "${smi:-}" ] && kill "$smi"
    rm -rf "$out"/*/work
    step done
} 2>&1 | tee "$out/log.txt"
