#!/usr/bin/env bash
# The GPU column of experiments/bench_scale.py on a lent GPU machine (#51), in one command there:
#   here:  bash ../shared/gpu/pack.sh            (builds .gpu/, ignored by git)
#   there: bash scripts/gpu_bench.sh             (run with .gpu carried along; $OUT is what comes back)
# The machine has no libLLVM and no OIDN package: the cases run on CUDA, their images not denoised (the row
# says so). About 3 minutes on an H200 (cold compiles included); rows.jsonl and table.md come back in $OUT.
set -euo pipefail
source .gpu/setup.sh
out=${OUT:-out/bench_scale_gpu}  # $OUT on the GPU machine; else under the ignored out/
mkdir -p "$out"
nvidia-smi --query-gpu=name,memory.total --format=csv,noheader > "$out/gpu.txt" || true
cp results/bench_scale/rows.jsonl "$out/rows.jsonl" 2>/dev/null || true  # the CPU rows stay beside the GPU ones
timeout 540 python3 experiments/bench_scale.py --device cuda --denoise none --out "$out" \
  --cases frame64,frame128,sequence64,frame256
