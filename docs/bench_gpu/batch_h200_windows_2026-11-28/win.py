import os, sys, tempfile, json
sys.path.insert(0, "benchmarks")
import warp as wp
wp.config.quiet = True
from bench_batch import write_scene, write_table
from warp_tube.batch import run_batch
from warp_tube.batch import framestore as fs
tmp = tempfile.mkdtemp(); scene = write_scene(tmp)
run_batch(scene, os.path.join(tmp, "warm"), write_table(tmp, 2, "warm.csv"), frames=2, device="cuda:0", workers=1, writers=0)
table = write_table(tmp, 16384)
for rep in range(2):
    for mb, kept in ((2048, 2), (512, 2), (512, 8), (1024, 4)):
        fs.WINDOW_BYTES = mb << 20; fs.FREE_WINDOWS_KEPT = kept
        r = run_batch(scene, os.path.join(tmp, f"o{rep}{mb}{kept}"), table, layout="arrays", frames=61, surface=True, device="cuda:0", workers=1)
        t = r.timings
        print(json.dumps({"window_MB": mb, "kept": kept, "wall": round(r.wall_s, 3), "copy_s": round(t["copy_s"], 3), "build_s": round(t["build_s"], 3),
                          "wait": round(r.write_wait_s, 3), "flush_wait": round(t["flush_wait_s"], 3), "prepare": round(r.prepare_s, 3)}), flush=True)
        fs.release_windows()
