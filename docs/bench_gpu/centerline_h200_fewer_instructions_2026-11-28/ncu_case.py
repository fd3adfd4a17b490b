import sys, os
sys.path.insert(0, os.path.join(os.getcwd(), "benchmarks"))
import bench_centerline as bc
extras = sys.argv[1] == "all"
r = bc.substep_case("cuda:0", 32, True if extras else False, reps=1, worlds=65536)
print({k: v for k, v in r.items() if k != "reps_s"})
