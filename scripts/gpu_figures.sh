#!/usr/bin/env bash
# The GPU figures of issue 37 in one run (about 7 minutes on one H100 with 16 cores): inference
# windows/s (batch 1 plain, as a CUDA graph and compiled; 256; 4096) beside the same machine's CPU,
# Suite-IN++ training s/epoch and GPU busy % with the data path on the host and on the device,
# and the live receiver's capacity for three-device walkers with the batched tracker on the GPU.
#
#   scripts/gpu_figures.sh OUT [quick]
#
# Everything lands in OUT (one folder per step, the log in OUT/log.txt); `quick` shrinks every
# step so that the script itself can be checked on a CPU-only machine in a minute or two.
# Each step has its own time limit, so a slow step costs its own figures, not the others'.
set -u
out=${1:?usage: scripts/gpu_figures.sh OUT [quick]}
quick=${2:-}
mkdir -p "$out"
export PYTHONUNBUFFERED=1 PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}src
py=${PYTHON:-python3}
wn() { "$py" -m wearnav "$@"; }
step() { echo "== $(date -u +%T) $*"; }

if [ -n "$quick" ]; then
    dev=cpu batches=1,16 epochs=1 walkers=2 cpu_s=4 dur=3 mrt=0.05
else
    dev=cuda batches=1,256,4096 epochs=4 walkers=25,50,100 cpu_s=20 dur=10 mrt=0.2
fi
{
    step machine
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1 || true
    nproc
    "$py" -c 'import torch; print("torch", torch.__version__, "cuda", torch.cuda.is_available())'

    step "inference on $dev"
    timeout 240 "$py" -m wearnav bench efficiency --device "$dev" --models suitein++ --batches "$batches" \
        --faster-b1 --min-run-time "$mrt" --out "$out/efficiency-sipp"
    timeout 90 "$py" -m wearnav bench efficiency --device "$dev" --models ronin,pdr --batches "$batches" \
        --min-run-time "$mrt" --out "$out/efficiency-others"
    step "inference on the CPU ($(nproc) threads)"
    CUDA_VISIBLE_DEVICES= timeout 90 "$py" -m wearnav bench efficiency --models suitein++ --batches 1,256 \
        --min-run-time "$mrt" --out "$out/efficiency-cpu"

    step training
    wn simulate --preset small --out "$out/sim" --overwrite >/dev/null
    for how in host device; do
        timeout 120 "$py" -m wearnav train suitein++ --data "$out/sim" --out "$out/train-$how" --epochs "$epochs" \
            --no-evaluate --data-on-"$how" >/dev/null
    done
    timeout 120 "$py" -m wearnav train suitein++ --data "$out/sim" --out "$out/train-device-b1024" --batch 1024 \
        --epochs "$epochs" --no-evaluate --data-on-device >/dev/null
    CUDA_VISIBLE_DEVICES= timeout 120 "$py" -m wearnav train suitein++ --data "$out/sim" --out "$out/train-cpu" \
        --epochs 2 --no-evaluate >/dev/null
    for f in "$out"/train-*/training.json; do
        "$py" - "$f" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))
keys = ("accelerator", "data_on_device", "batch", "train_windows", "epochs_run", "s_per_epoch", "gpu_busy_pct", "best_val_vel_mse")
print(sys.argv[1].split("/")[-2], {k: r.get(k) for k in keys})
EOF
    done
    rm -rf "$out/sim" "$out"/train-*/checkpoints

    step "live receiver, three-device walkers, tracker batched on $dev"
    timeout 330 "$py" -m wearnav live bench --walkers "$walkers" --devices all --cpu-s "$cpu_s" --duration "$dur" \
        --out "$out/live"
    step done
} 2>&1 | tee "$out/log.txt"
