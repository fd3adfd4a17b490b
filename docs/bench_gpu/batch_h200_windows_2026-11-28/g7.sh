# the frames' windows kept for reuse: GPU tests, then the arrays batch before/after alternated
source .gpu-run/env.sh
mkdir -p $OUT/r
timeout 200 python -m pytest -q -p no:cacheprovider -m gpu tests/test_framestore.py tests/test_batch_gpu.py > $OUT/r/gpu_tests.txt 2>&1; echo "rc=$?" >> $OUT/r/gpu_tests.txt; tail -2 $OUT/r/gpu_tests.txt
one() { timeout 120 python benchmarks/bench_batch.py --variants 16384 --frames 61 --layouts arrays --device cuda:0 2>>$OUT/r/err.txt > $OUT/r/b_$1_$2.json; python - $OUT/r/b_$1_$2.json $1 <<'P'
import json, sys
d = json.load(open(sys.argv[1])); r = d["runs"][0]; s = r["split_s"]
print(sys.argv[2], "wall %.2f kern %.2f other %.2f (%.0f%%) wait %.2f floor %.2f" % (r["wall_s"], r["kernels_s"], r["other_s"], 100*r["other_fraction"], r["write_wait_s"], r["floor_s"]), " ".join("%s=%.3f" % (k[:8], v) for k, v in s.items()))
P
}
for k in 1 2 3; do
  (cd /tmp/wt/.gpu-run/old4 && PYTHONPATH=/tmp/site:/tmp/wt/.gpu-run/old4 one old $k)
  one new $k
done 2>&1 | tee $OUT/r/pair.txt
