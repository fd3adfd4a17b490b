import json, sys
for f in sys.argv[1:]:
    t = open(f).read(); i = t.find("{")
    if i < 0: print(f, "no json"); continue
    d = json.loads(t[i:])
    for r in d["runs"]:
        s = r["split_s"]
        print(f"{f} {r['layout']} chunks={r['chunks']} wall={r['wall_s']:.2f} kern={r['kernels_s']:.3f} other={r['other_s']:.3f} ({100*r['other_fraction']:.1f}%) wait={r['write_wait_s']:.2f} floor={r['floor_s']:.2f} w/b={r['wall_over_bound']:.2f} | " + " ".join(f"{k.replace('_s','')}={v:.3f}" for k, v in s.items()))
