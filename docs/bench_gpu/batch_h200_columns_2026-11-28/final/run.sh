# the copying thread set up while the variants are read: arrays batch, before (24b712f.. HEAD~) and after alternated
source .gpu-run/env.sh
mkdir -p $OUT/r
one() { timeout 150 python benchmarks/bench_batch.py --variants 16384 --frames 61 --layouts arrays --device cuda:0 2>>$OUT/r/err.txt > $OUT/r/b_$1_$2.json; python /tmp/wt/.gpu-run/summ.py $OUT/r/b_$1_$2.json | sed "s#^#$1 #"; }
for k in 1 2 3; do
  (cd /tmp/wt/.gpu-run/old7 && PYTHONPATH=/tmp/site:/tmp/wt/.gpu-run/old7 one old $k)
  one new $k
done 2>&1 | tee $OUT/r/pair.txt
timeout 200 python -m pytest -q -p no:cacheprovider -m gpu tests/test_framestore.py tests/test_batch_gpu.py > $OUT/r/gpu_tests.txt 2>&1; echo "rc=$?" >> $OUT/r/gpu_tests.txt; tail -2 $OUT/r/gpu_tests.txt
cd $OUT && tar czf r22.tgz r && rm -rf r
