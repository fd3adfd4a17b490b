"""cProfile of the simulating thread of one arrays batch (16,384 variants, 61 frames) on cuda:0."""
import cProfile, os, pstats, sys, tempfile, io
sys.path.insert(0, "benchmarks")
import warp as wp
wp.config.quiet = True
from bench_batch import write_scene, write_table
from warp_tube.batch import run_batch
n = int(os.environ.get("N", "16384"))
tmp = tempfile.mkdtemp()
scene = write_scene(tmp)
run_batch(scene, os.path.join(tmp, "warm"), write_table(tmp, 2, "warm.csv"), frames=2, device="cuda:0", workers=1, writers=0)
table = write_table(tmp, n)
pr = cProfile.Profile()
pr.enable()
r = run_batch(scene, os.path.join(tmp, "out"), table, layout="arrays", frames=61, surface=True, device="cuda:0", workers=1)
pr.disable()
print("wall", r.wall_s, "prepare", r.prepare_s, "books", r.books_s, "wait", r.write_wait_s, r.timings)
pr.dump_stats(os.path.join(os.environ["OUT"], "r", "batch.prof"))
s = io.StringIO(); pstats.Stats(pr, stream=s).sort_stats("tottime").print_stats(45); print(s.getvalue()[:9000])
s = io.StringIO(); pstats.Stats(pr, stream=s).sort_stats("cumulative").print_stats(60); print(s.getvalue()[:12000])
