# issue 14: per-frame host costs against the chunk's size and the writer threads
source .gpu-run/env.sh
mkdir -p $OUT/r
run() { timeout 150 python benchmarks/bench_batch.py --frames 61 --layouts arrays --device cuda:0 "$@" 2>>$OUT/r/err.txt | python -c "
import json,sys
d=json.load(sys.stdin); r=d['runs'][0]; s=r['split_s']
print('$*', 'wall %.2f kern %.2f other %.2f (%.0f%%) wait %.2f floor %.2f' % (r['wall_s'], r['kernels_s'], r['other_s'], 100*r['other_fraction'], r['write_wait_s'], r['floor_s']), ' '.join('%s=%.3f' % (k[:8], v) for k, v in s.items()))
" | tee -a $OUT/r/g6.txt; }
run --variants 1024 --chunk 256
run --variants 16384 --chunk 4096
run --variants 16384 --chunk 4096 --writers 2
run --variants 1024 --chunk 256
run --variants 16384 --chunk 4096
run --variants 16384 --chunk 4096 --writers 2
