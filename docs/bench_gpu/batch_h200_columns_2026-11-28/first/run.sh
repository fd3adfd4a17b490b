# the batch's host side (arrays layout: the surface's points alone; plain tables as columns): GPU batch tests,
# then the arrays batch before (d6696b8) and after alternated, three rounds; files once each
source .gpu-run/env.sh
mkdir -p $OUT/r
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $OUT/r/gpu.txt; date -u >> $OUT/r/gpu.txt; nproc >> $OUT/r/gpu.txt
timeout 300 python -m pytest -q -p no:cacheprovider -m gpu tests/test_framestore.py tests/test_batch_gpu.py tests/test_onchip.py tests/test_paths.py > $OUT/r/gpu_tests.txt 2>&1; echo "rc=$?" >> $OUT/r/gpu_tests.txt; tail -2 $OUT/r/gpu_tests.txt
one() { timeout 150 python benchmarks/bench_batch.py --variants 16384 --frames 61 --layouts $3 --device cuda:0 --floor-variants 256 2>>$OUT/r/err.txt > $OUT/r/b_$1_$3_$2.json; python /tmp/wt/.gpu-run/summ.py $OUT/r/b_$1_$3_$2.json | sed "s#^#$1 #"; }
for k in 1 2 3; do
  (cd /tmp/wt/.gpu-run/old7 && PYTHONPATH=/tmp/site:/tmp/wt/.gpu-run/old7 one old $k arrays)
  one new $k arrays
done 2>&1 | tee $OUT/r/pair.txt
(cd /tmp/wt/.gpu-run/old7 && PYTHONPATH=/tmp/site:/tmp/wt/.gpu-run/old7 one old 1 files) 2>&1 | tee -a $OUT/r/pair.txt
one new 1 files 2>&1 | tee -a $OUT/r/pair.txt
cd $OUT && tar czf r17.tgz r && rm -rf r
