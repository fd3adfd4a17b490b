"""Where the simulating thread's 'handing frames over' goes: timers around the FrameStore's and the
surface builder's calls, in one arrays batch of 16,384 variants (chunks of 4,096) on cuda:0."""
import os, sys, tempfile, time, json, collections
sys.path.insert(0, "benchmarks")
import warp as wp
wp.config.quiet = True
from bench_batch import write_scene, write_table
from warp_tube.batch import run_batch
from warp_tube.batch import framestore as fs, engine
from warp_tube.surface import builder as sb
acc = collections.defaultdict(float); cnt = collections.Counter()
def timed(obj, name, label):
    f = getattr(obj, name)
    def w(*a, **k):
        t = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            if __import__("threading").current_thread() is __import__("threading").main_thread():
                acc[label] += time.perf_counter() - t; cnt[label] += 1
    setattr(obj, name, w)
timed(fs.FrameStore, "store", "store")
timed(fs.FrameStore, "hand_over", "hand_over")
timed(fs.FrameStore, "__init__", "framestore_init")
timed(sb.SurfaceBuilder, "compute", "surface_compute")
timed(engine, "_store_frame", "store_frame")
timed(wp, "empty", "wp.empty")
n = int(os.environ.get("N", "16384"))
tmp = tempfile.mkdtemp()
scene = write_scene(tmp)
run_batch(scene, os.path.join(tmp, "warm"), write_table(tmp, 2, "warm.csv"), frames=2, device=os.environ.get("DEV", "cuda:0"), workers=1, writers=0)
table = write_table(tmp, n)
for rep in range(2):
    acc.clear(); cnt.clear()
    r = run_batch(scene, os.path.join(tmp, f"out{rep}"), table, layout="arrays", frames=61, surface=True, device=os.environ.get("DEV", "cuda:0"), workers=1,
                  chunk=int(os.environ.get("CHUNK", "4096")))
    print(json.dumps({"wall": r.wall_s, "copy_s": r.timings["copy_s"], "build_s": r.timings["build_s"],
                      "acc": {k: round(v, 4) for k, v in acc.items()}, "count": dict(cnt)}))
