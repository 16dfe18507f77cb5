#!/usr/bin/env bash
# Issue 37's batched live tracker on a GPU machine, in one device call (about 8 minutes with 16 cores):
#
#   1. three-device walkers tracked in the receiver: one `Crowd` thread, one batched forward pass of
#      the shipped Suite-IN++ per tick for every session, on the GPU (`SharedModels` picks CUDA);
#   2. three-device walkers tracked by 12 `wearnav live track` processes beside a storing receiver,
#      each batching its own sessions on the same GPU.
#
#   scripts/gpu_live.sh OUT [quick]
#
# OUT gets log.txt, nvidia-smi's utilisation each second (gpu.csv) and one page per step
# (in-process/, trackers/: results.md and results.json). `quick` shrinks both steps so that the
# script can be checked on a CPU-only machine in a few minutes. Each step has its own time limit.
set -u
out=${1:?usage: scripts/gpu_live.sh OUT [quick]}
quick=${2:-}
mkdir -p "$out"
export PYTHONUNBUFFERED=1 PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}src
py=${PYTHON:-python3}
step() { echo "== $(date -u +%T) $*"; }

if [ -n "$quick" ]; then
    w_in=2 w_tr=2 trackers=1 cpu_s=4 dur=3
else
    w_in=8,16,32 w_tr=32,64 trackers=12 cpu_s=20 dur=10
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

    step "three-device walkers, tracked in the receiver"
    timeout 250 "$py" -m wearnav live bench --walkers "$w_in" --devices all --cpu-s "$cpu_s" --duration "$dur" \
        --out "$out/in-process"
    step "three-device walkers, $trackers tracker processes"
    timeout 270 "$py" -m wearnav live bench --walkers "$w_tr" --devices all --trackers "$trackers" --cpu-s "$cpu_s" \
        --duration "$dur" --out "$out/trackers"
    [ -n "${smi:-}" ] && kill "$smi"
    rm -rf "$out"/*/work
    step done
} 2>&1 | tee "$out/log.txt"
