source .gpu-run/env.sh
mkdir -p $OUT/r
NCU=$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)
echo "ncu: $NCU" > $OUT/r/tools.txt; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader >> $OUT/r/tools.txt
if [ -n "$NCU" ]; then
  for c in all minimal; do
    timeout 240 $NCU --kernel-name regex:substeps_onchip --launch-count 1 --section SpeedOfLight --section Occupancy --section WarpStateStats --section SchedulerStats --section InstructionStats --section LaunchStats --section ComputeWorkloadAnalysis python .gpu-run/ncu_case.py $c > $OUT/r/ncu_$c.txt 2>&1
  done
fi
cat $OUT/r/tools.txt; tail -5 $OUT/r/ncu_all.txt 2>/dev/null
cd $OUT && tar czf r.tgz r && rm -rf r
