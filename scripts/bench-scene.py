#!/usr/bin/env python3
"""Side-by-side scene timings of one or more amr-render binaries: extraction, BVH build, frame.

usage: scripts/bench-scene.py RUNS FILE.amrk ISO SIZE BINARY [BINARY...] [-- EXTRA ARGS...]

For each run and each binary in turn (interleaved, so that the binaries see the same machine
state), the file is first read into the page cache, then a fresh process renders it
(`BINARY FILE --iso ISO --size SIZE -o OUT.exr --stats-json ...` plus any extra arguments).
Prints, per binary, the medians of extract_ms, bvh_ms and render_ms from the statistics, the BVH
build rate in active octants per second and the largest peak RSS.
"""
import json
import os
import statistics
import subprocess
import sys
import tempfile


def main():
    args = sys.argv[1:]
    extra = []
    if "--" in args:
        i = args.index("--")
        args, extra = args[:i], args[i + 1:]
    if len(args) < 5:
        sys.exit(__doc__)
    runs, path, iso, size, binaries = int(args[0]), args[1], args[2], args[3], args[4:]
    keys = ["extract_ms", "bvh_ms", "render_ms"]
    seen = {b: {k: [] for k in keys + ["peak_rss_bytes"]} for b in binaries}
    active = None
    with tempfile.TemporaryDirectory() as tmp:
        out, img = os.path.join(tmp, "stats.json"), os.path.join(tmp, "out.exr")
        for _ in range(runs):
            for b in binaries:
                subprocess.run(["cat", path], stdout=subprocess.DEVNULL, check=True)
                cmd = [b, path, "--iso", iso, "--size", size, "-o", img, "--stats-json", out]
                subprocess.run(cmd + extra, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                               check=True)
                with open(out) as f:
                    stats = json.load(f)
                for k in seen[b]:
                    seen[b][k].append(stats[k])
                active = stats["active_octants"]
    print(f"{path} iso {iso}, {active} active octants, {runs} runs, size {size} {' '.join(extra)}")
    print("| binary | extract ms | BVH ms | M octants/s (BVH) | frame ms | peak RSS MB |")
    print("|---|---|---|---|---|---|")
    for b in binaries:
        m = {k: statistics.median(seen[b][k]) for k in keys}
        rss = max(seen[b]["peak_rss_bytes"]) / 1e6
        rate = active / m["bvh_ms"] / 1e3
        print(f"| {b} | {m['extract_ms']:.0f} | {m['bvh_ms']:.0f} | {rate:.2f} | "
              f"{m['render_ms']:.0f} | {rss:.0f} |")


if __name__ == "__main__":
    main()
