"""Instructions of the on-chip kernel's substep loop, counted in its machine code, without a GPU.

Warp compiles the kernel to PTX for ``--arch`` (its own NVRTC, no driver needed), ``ptxas`` turns
that into machine code as Warp's CUDA build would (the same register cap), and the substep loop's
instructions are counted and, with ``--lines``, attributed to the kernel's source lines (the
outermost line of ``kernels/onchip.py`` each instruction was inlined into). The static count of the
loop follows what Nsight Compute measures per tube and substep (one warp a 32-point tube) to a few
percent: code in branches no lane takes (a half turn in :func:`~warp_tube.kernels.frames.rotate_minimal`)
is counted but not run. It answers "did this change make the kernel shorter" in seconds; the speed
itself is measured on a GPU (``bench_centerline.py``).

Needs ``ptxas``, ``cuobjdump`` and ``nvdisasm`` (CUDA 12.8 or later for Warp 1.19's PTX; the
``nvidia-cuda-nvcc``, ``nvidia-cuda-cuobjdump`` and ``nvidia-cuda-nvdisasm`` Python packages carry
them) on ``PATH`` or in ``--cuda-bin``.

    python benchmarks/sass_profile.py                  # every feature and minimal, 32-point tubes
    python benchmarks/sass_profile.py --lines 25       # and the 25 costliest source lines
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

import warp as wp

from warp_tube.centerline.explicit import ONCHIP_MAX_REGISTERS
from warp_tube.kernels.onchip import make_onchip_kernel
from warp_tube.kernels.springs import Features

INSTR = re.compile(r"\s+/\*([0-9a-f]{4,6})\*/\s+(.*?);")
WHERE = re.compile(r'"([^"]+)", line (\d+)')
BRANCH_BACK = re.compile(r"@!?U?P\d+\s+BRA\s+(?:!?U?P\d, )?(?:0x([0-9a-f]+)|`\(\.L_x_(\d+)\))")


def tool(name: str, cuda_bin: str | None) -> str:
    path = os.path.join(cuda_bin, name) if cuda_bin else shutil.which(name)
    if not path or not os.path.exists(path):
        sys.exit(f"sass_profile: {name} not found (put the CUDA binaries on PATH or pass --cuda-bin)")
    return path


def machine_code(every: bool, arch: int, block: int, cuda_bin: str | None, work: str, free: bool = False) -> str:
    """The disassembly (with inlined source lines) of the shuffle-exchange on-chip kernel."""
    features = Features(*([True] * 8)) if every else Features()
    regs = ONCHIP_MAX_REGISTERS if every else None  # the cap Warp's launch applies where it takes more
    kernel = make_onchip_kernel(features, block, 1 if every else 0, regs, "shuffle", free and every)
    out = os.path.join(work, "every" if every else "minimal")
    wp.compile_aot_module(kernel.module, arch=arch, module_dir=out, use_ptx=True)
    (ptx,) = [os.path.join(out, f) for f in os.listdir(out) if f.endswith(".ptx")]
    clean = ptx + ".clean"
    with open(ptx, "rb") as src, open(clean, "wb") as dst:
        dst.write(src.read().replace(b"\0", b""))
    cubin = os.path.join(out, "kernel.cubin")
    for cmd in ([tool("ptxas", cuda_bin), f"-arch=sm_{arch}", "-O3", clean, "-o", cubin], [tool("nvdisasm", cuda_bin), "-gi", "-c", cubin]):
        run = subprocess.run(cmd, capture_output=True, text=True)
        if run.returncode:
            sys.exit(f"sass_profile: {os.path.basename(cmd[0])} failed ({run.stderr.strip()[-300:]}); "
                     "it must read the PTX Warp writes (CUDA 12.8 or later for Warp 1.19)")
    return run.stdout


def parse(dis: str):
    """``[(address, text, outermost onchip.py line)]`` of every instruction and the addresses of
    the branch labels."""
    rows, block, line, labels, pending = [], [], 0, {}, []
    for text in dis.splitlines():
        if "//##" in text:
            block.append(text)
            continue
        label = re.match(r"\.L_x_(\d+):", text.strip())
        if label:
            pending.append(label.group(1))
            continue
        m = INSTR.match(text)
        if not m:
            continue
        for name in pending:
            labels[name] = int(m.group(1), 16)
        pending = []
        if block:
            frames = [(f, int(n)) for b in block for f, n in WHERE.findall(b) if f.endswith("onchip.py")]
            line = frames[-1][1] if frames else 0
            block = []
        rows.append((int(m.group(1), 16), m.group(2).strip(), line))
    return rows, labels


def substep_loop(rows, labels):
    """The instructions of the substep loop: the innermost loop (a backward conditional branch)
    around the first warp shuffle (the neighbours' exchange that opens every substep)."""
    first_shuffle = next(a for a, t, _ in rows if "SHFL" in t)
    loops = []
    for a, t, _ in rows:
        m = BRANCH_BACK.match(t)
        if m:
            target = int(m.group(1), 16) if m.group(1) else labels.get(m.group(2), a + 1)
            if target < a:
                loops.append((target, a))
    lo, hi = min((span for span in loops if span[0] <= first_shuffle <= span[1]), key=lambda s: s[1] - s[0])
    return [r for r in rows if lo <= r[0] <= hi]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arch", type=int, default=90, help="SM architecture (90: H100, H200)")
    ap.add_argument("--block", type=int, default=128, help="threads per block")
    ap.add_argument("--cuda-bin", default=None, help="folder with ptxas, cuobjdump and nvdisasm")
    ap.add_argument("--lines", type=int, default=0, help="also print this many costliest source lines")
    ap.add_argument("--free", action="store_true", help="every feature with tubes free to turn at their start (one more scan)")
    a = ap.parse_args()
    wp.config.quiet = True
    wp.config.lineinfo = True
    wp.init()
    res = {"arch": a.arch, "block": a.block, "free_to_turn": a.free, "warp": wp.config.version}
    with tempfile.TemporaryDirectory() as work:
        for every in (False, True):
            loop = substep_loop(*parse(machine_code(every, a.arch, a.block, a.cuda_bin, work, a.free)))
            ops = collections.Counter(re.sub(r"^@!?U?P\w+\s+", "", t).split()[0].split(".")[0] for _, t, _ in loop)
            name = "all_features" if every else "minimal"
            res[name] = {"loop_instructions": len(loop), "spill_loads": ops["LDL"], "spill_stores": ops["STL"],
                         "shuffles": ops["SHFL"], "branches": ops["BRA"]}  # fmt: skip
            if a.lines:
                src = open(make_onchip_kernel.__wrapped__.__code__.co_filename).read().splitlines()
                per_line = collections.Counter(line for _, _, line in loop)
                res[name]["lines"] = [f"{n:4d}  {line:4d}  {src[line - 1].strip()[:90] if line else '?'}" for line, n in per_line.most_common(a.lines)]
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
