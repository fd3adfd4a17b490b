# the final kernel: the last timed kernel (531fb53) and HEAD alternated; ncu counts; the arrays batch
source .gpu-run/env.sh
mkdir -p $OUT/r
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader > $OUT/r/gpu.txt; date -u >> $OUT/r/gpu.txt
for rep in 1 2 3; do
  CASES=minimal,all,all_free POINTS=32 PYTHONPATH=/tmp/site:/tmp/wt/.gpu-run/old5 timeout 100 python .gpu-run/cmp.py /tmp/wt/.gpu-run/old5 >> $OUT/r/cmp.jsonl 2>>$OUT/r/cmp_old.err
  CASES=minimal,all,all_free POINTS=32 timeout 100 python .gpu-run/cmp.py /tmp/wt >> $OUT/r/cmp.jsonl 2>>$OUT/r/cmp_new.err
done
CASES=all,all_free POINTS=20 PYTHONPATH=/tmp/site:/tmp/wt/.gpu-run/old5 timeout 100 python .gpu-run/cmp.py /tmp/wt/.gpu-run/old5 >> $OUT/r/cmp.jsonl 2>>$OUT/r/cmp_old.err
CASES=all,all_free POINTS=20 timeout 100 python .gpu-run/cmp.py /tmp/wt >> $OUT/r/cmp.jsonl 2>>$OUT/r/cmp_new.err
python - <<'P'
import json, os
for l in open(os.environ["OUT"] + "/r/cmp.jsonl"):
    d = json.loads(l); print(d["tree"][-4:], d["points"], d["case"], round(d["time_per_substep_us"], 2), "%.3g" % d["hub_steps_per_s"], d.get("register_count"), d.get("local_memory_size"))
P
NCU=$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)
echo "ncu: $NCU" >> $OUT/r/gpu.txt
if [ -n "$NCU" ]; then
  for c in all minimal; do
    timeout 120 $NCU --kernel-name regex:substeps_onchip --launch-count 1 --section SpeedOfLight --section Occupancy --section WarpStateStats --section SchedulerStats --section InstructionStats --section LaunchStats --section ComputeWorkloadAnalysis python .gpu-run/ncu_case.py $c > $OUT/r/ncu_$c.txt 2>&1
  done
  grep -h "Executed Instructions  \|Issue Slots Busy\|Registers Per" $OUT/r/ncu_*.txt
fi
for k in 1 2; do
  timeout 100 python benchmarks/bench_batch.py --variants 16384 --frames 61 --layouts arrays --device cuda:0 > $OUT/r/batch_arrays_$k.json 2>>$OUT/r/batch.err
  python .gpu-run/summ.py $OUT/r/batch_arrays_$k.json
done
cd $OUT && tar czf r.tgz r && rm -rf r
