#!/usr/bin/env python3
"""Summarises a per-address instruction histogram of bench-m4 (written by
qemu-pc-histogram.c between profile_start and profile_end): instructions per
typical tick by stage, by innermost function and by source line, using the
ELF's line tables with inlined frames (llvm-symbolizer). Approximate where
LTO merged code from several lines. Usage: profile.py ELF HISTOGRAM"""
import collections
import re
import shutil
import subprocess
import sys

elf, hist = sys.argv[1], sys.argv[2]
lines = open(hist).read().split("\n")
win = int(lines[0].split()[1])
data = [(l.split()[0], int(l.split()[1])) for l in lines[1:] if l.strip()]
sym = shutil.which("llvm-symbolizer")
if sym is None:
    sys.exit("llvm-symbolizer not found (apt-get install llvm)")
out = subprocess.run([sym, "--obj=" + elf, "--inlines", "--demangle"],
                     input=("\n".join(a for a, _ in data) + "\n").encode(),
                     capture_output=True, check=True).stdout.decode()
blocks = out.strip("\n").split("\n\n")
assert len(blocks) == len(data)


def short(f):
    f = re.sub(r"::h[0-9a-f]{16}$", "", f)
    for _ in range(3):
        f = re.sub(r"<[^<>]*>", "", f)
    return f


def stage(chain):
    s = " ".join(chain)
    for key, name in [("estimator", "estimator"), ("PaperCurve", "reference"),
                      ("trajectory", "reference"), ("pacer", "pacer"),
                      ("governor", "pacer"), ("health", "pacer"),
                      ("controller::", "controller step"), ("asmc", "controller step"),
                      ("eso::", "controller step"), ("fault_observer", "controller step"),
                      ("kinematic", "controller step"), ("tracking", "controller step"),
                      ("read_wheels", "encoders"), ("encoder", "encoders"),
                      ("duty_for", "duty"), ("motor", "duty"), ("timing", "LoopTimer"),
                      ("memcpy", "memcpy/memset"), ("memset", "memcpy/memset"),
                      ("memclr", "memcpy/memset")]:
        if key in s:
            return name
    if "control_loop" not in s and ("black_box" in s or "bench_m4" in s):
        return "benchmark harness"
    return "runtime (tick body, report, supervisor)"


by_stage, by_fn, by_line = collections.Counter(), collections.Counter(), collections.Counter()
for (_, c), b in zip(data, blocks):
    fr = b.split("\n")
    chain = [short(fr[i]) for i in range(0, len(fr) - 1, 2)]
    loc = re.sub(r"^.*/(src|library)/", "", fr[1])
    by_stage[stage(chain)] += c
    by_fn[chain[0]] += c
    by_line[(re.sub(r":\d+$", "", loc), chain[0])] += c
total = sum(c for _, c in data)
print(f"{win} typical ticks profiled, {total / win:.0f} instructions per tick")
print("\n## by stage (per tick)")
for k, v in by_stage.most_common():
    print(f"{v / win:8.1f}  {k}")
print("\n## by innermost (inlined) function, top 30")
for k, v in by_fn.most_common(30):
    print(f"{v / win:8.1f}  {k}")
print("\n## by source line, top 40")
for (loc, fn), v in by_line.most_common(40):
    print(f"{v / win:8.1f}  {loc}  {fn}")
