"""Side-by-side on-chip cases for one tree: python cmp.py TREE [maxreg ...] -> JSON lines."""
import json, os, sys
tree = sys.argv[1]
sys.path.insert(0, os.path.join(tree, "benchmarks"))
import warp as wp
wp.config.quiet = True
import bench_centerline as bc
from warp_tube.centerline import explicit
from warp_tube.sim.simulation import Simulation
regs = [int(r) for r in sys.argv[2:]] or [None]
P = int(os.environ.get("POINTS", "32"))
EX = os.environ.get("EXCHANGE", "auto")
CASES = os.environ.get("CASES", "minimal,all,curved,line,all_free").split(",")
wp.init()
n = Simulation(bc.scene(P, True), device="cpu", surface=False).substeps
for reg in regs:
    if reg is not None:
        explicit.ONCHIP_MAX_REGISTERS = reg
    for name, extras, pinned in (("minimal", False, (0, 1)), ("all", True, (0, 1)), ("curved", {"curved"}, (0, 1)),
                                 ("line", {"assistant_line"}, (0, 1)), ("all_free", True, (0,))):
        if (reg is not None and name not in ("all", "all_free")) or name not in CASES:
            continue
        c = bc.substep_case("cuda:0", P, extras, 5, worlds=65536, substeps=n, onchip=True, pinned=pinned, exchange=EX)
        c.pop("reps_s", None)
        print(json.dumps({"tree": tree, "maxreg": reg, "case": name, **c}), flush=True)
