# the final code: the whole GPU test suite
source .gpu-run/env.sh
mkdir -p $OUT/r
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $OUT/r/gpu.txt; date -u >> $OUT/r/gpu.txt
timeout 560 python -m pytest -m gpu -q -p no:cacheprovider > $OUT/r/gpu_tests.txt 2>&1; echo "rc=$?" >> $OUT/r/gpu_tests.txt
tail -3 $OUT/r/gpu_tests.txt
cd $OUT && tar czf r13.tgz r && rm -rf r
