#!/usr/bin/env python3
"""A frame's clock split into primary walks, shadow and AO walks, their set-up and the AO filter,
from `perf record` profiles with call stacks of one-thread renders.

    perf record -e cpu-clock -F 4000 --call-graph dwarf,65528 -o p1.data \\
        amr-render FILE ARGS --threads 1 --exr-compression none -o x.exr
    scripts/perf-split.py 4000 p1.data [p2.data ...]

Each sample under `render_frame` goes to the first part below whose callers are all on its
stack; the times are per profile (the mean of the profiles given), in ms at the sampling rate
given (Hz). Samples under `render_frame` that match none are "other": shading, the rows' and
pixels' own work, allocations and page faults; the largest of their innermost functions follow.
"""
import collections
import subprocess
import sys

PARTS = [
    ("AO filter", ["filter_rows"]),
    ("AO walks", ["TileAo::trace", "occluded_in_turn"]),
    ("AO set-up", ["TileAo::trace"]),
    ("shadow walks", ["KeyShadow::trace", "occluded_in_turn"]),
    ("shadow set-up", ["KeyShadow::trace"]),
    ("primary: smooth gradients", ["smooth_gradients"]),
    ("primary walks", ["TileHits::trace"]),
    ("transparent layers", ["TileLayers::trace"]),
]


def stacks(path):
    out = subprocess.run(["perf", "script", "-i", path, "--no-inline", "-F", "ip,sym"],
                         capture_output=True, text=True, check=True).stdout
    for sample in out.split("\n\n"):
        frames = [l.strip().split(None, 1)[-1] for l in sample.strip().split("\n") if l.strip()]
        if frames:
            yield frames


def main():
    hz = float(sys.argv[1])
    files = sys.argv[2:]
    parts, leaves = collections.Counter(), collections.Counter()
    for path in files:
        for frames in stacks(path):
            if not any("render_frame" in f for f in frames):
                continue
            part = next((name for name, callers in PARTS
                         if all(any(c in f for f in frames) for c in callers)), "other")
            parts[part] += 1
            if part == "other":
                leaves[frames[0][:100]] += 1
    ms = lambda n: n / hz * 1000 / len(files)
    for name, n in parts.most_common():
        print(f"{name:28} {ms(n):8.1f} ms")
    print(f"{'render_frame':28} {ms(sum(parts.values())):8.1f} ms")
    for leaf, n in leaves.most_common(10):
        print(f"    other: {ms(n):6.1f} ms {leaf}")


if __name__ == "__main__":
    main()
