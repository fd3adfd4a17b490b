# the final code: GPU tests of the batch, paths and on-chip kernel
source .gpu-run/env.sh
mkdir -p $OUT/r
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $OUT/r/gpu.txt; date -u >> $OUT/r/gpu.txt
timeout 330 python -m pytest -q -p no:cacheprovider -m gpu tests/test_framestore.py tests/test_batch_gpu.py tests/test_onchip.py tests/test_paths.py > $OUT/r/gpu_tests.txt 2>&1; echo "rc=$?" >> $OUT/r/gpu_tests.txt; tail -3 $OUT/r/gpu_tests.txt
cd $OUT && tar czf r23.tgz r && rm -rf r
