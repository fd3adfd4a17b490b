"""Noisy synthetic tubes: ends right and axis error, for the code on sys.path."""
import sys, json, numpy as np, logging
logging.disable(logging.WARNING)
import warp as wp
wp.config.quiet = True
from warp_tube.bench.synthetic_tubes import synthetic_cases
from warp_tube.extract.pipeline import extract_centerline
import trimesh
KIND = {"open": "open", "flat": "cut", "round": "closed"}
out = []
for level in (0.1, 0.2):
    rng = np.random.default_rng(0)
    for case in synthetic_cases():
        v = np.asarray(case.mesh.vertices).copy()
        r = float(np.mean(case.radius))
        v += rng.normal(size=v.shape) * level * r
        m = trimesh.Trimesh(v, case.mesh.faces, process=False)
        try:
            t = extract_centerline(m)
        except Exception as e:
            out.append(dict(case=case.name, level=level, error=str(e)[:80])); continue
        ends = tuple(e.kind for e in t.ends)
        truth = tuple(KIND[e] for e in case.ends)
        # axis error of interior hubs: distance to the true curve / local radius
        d = np.linalg.norm(t.points[1:-1, None] - case.curve[None, ::4], axis=-1)
        j = d.argmin(axis=1)
        err = (d[np.arange(len(j)), j] / case.radius[::4][j])
        right = ends == truth or ends == truth[::-1]
        out.append(dict(case=case.name, level=level, ends=ends, truth=truth, right=right, axis_max=float(err.max()), axis_mean=float(err.mean()),
                        length=float(t.tip_to_tip), true_length=case.length))
wrong = [o for o in out if not o.get("right")]
print(json.dumps(dict(runs=len(out), wrong_ends=len(wrong), worst_axis=max(o.get("axis_max", 0) for o in out),
                      rows=out), indent=1))
