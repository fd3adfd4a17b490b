#!/usr/bin/env bash
# warp-tube bench on a CUDA GPU, with Newton on the same GPU (PyElastica has no GPU path and is left out).
#
# Usage, from the repository root on the GPU machine (each step is meant to stay under 10 minutes;
# REPEAT=N sets the repetitions, 3 and 2 by default; REPEAT=1 if a step runs too long):
#   bash benchmarks/gpu_bench.sh accuracy OUT   # static problems, first frequency
#   bash benchmarks/gpu_bench.sh speed OUT      # throughput, 1 to 65,536 tubes
# Then, where matplotlib is installed (here or on the GPU machine):
#   warp-tube bench --replot OUT/accuracy/results.json -o OUT/accuracy
#   warp-tube bench --replot OUT/speed/results.json -o OUT/speed
#   mkdir -p docs/bench_gpu && cp OUT/accuracy/error_vs_time.png OUT/accuracy/convergence.png OUT/speed/throughput.png docs/bench_gpu/
#   cp OUT/accuracy/report.md docs/bench_gpu/accuracy.md && cp OUT/speed/report.md docs/bench_gpu/speed.md
#   cp OUT/accuracy/results.json docs/bench_gpu/accuracy.json && cp OUT/speed/results.json docs/bench_gpu/speed.json
#
# Needs warp-lang >= 1.19 and this package's core dependencies installed, and Newton: with no network,
# put newton-1.8.0-py3-none-any.whl (pure Python, 8.6 MB; it requires only warp-lang >= 1.17) in
# WHEELS (default ./wheels) first; on a machine with a package index: pip download --no-deps -d wheels newton==1.8.0
set -euo pipefail
step=${1:?accuracy or speed}
out=${2:-bench-gpu}
wheels=${WHEELS:-wheels}
py=${PYTHON:-python}
if ! "$py" -c "import newton" 2>/dev/null; then
    "$py" -m pip install --no-index --no-deps --find-links "$wheels" newton==1.8.0
fi
"$py" -c "import warp as wp; wp.init(); assert wp.get_cuda_device_count() > 0, 'no CUDA device'"
case "$step" in
    accuracy) "$py" -m warp_tube bench --suite accuracy --peers newton --device cuda:0 --repeat "${REPEAT:-3}" -o "$out/accuracy" ;;
    speed) "$py" -m warp_tube bench --suite speed --peers newton --device cuda:0 --repeat "${REPEAT:-2}" -o "$out/speed" ;;
    *) echo "unknown step $step: expected accuracy or speed" >&2; exit 2 ;;
esac
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > "$out/$step/gpu.txt" || true
