#!/usr/bin/env python3
"""Side-by-side extraction timings of one or more amr-render binaries.

usage: scripts/bench-extract.py RUNS FILE.amrk ISO BINARY [BINARY...]

For each run and each binary in turn (interleaved, so that the binaries see the same machine
state), the file is first read into the page cache, then a fresh process runs
`BINARY extract FILE --iso ISO --iso ISO --runs 1 --stats-json ...`: the first extraction of a
session (tight leaf ranges computed) and a later one (ranges kept). Prints, per binary, the
medians of both with file cells per core-second, and the first-isovalue times of every run.
"""
import json
import os
import statistics
import subprocess
import sys
import tempfile


def main():
    if len(sys.argv) < 5:
        sys.exit(__doc__)
    runs, path, iso, binaries = int(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4:]
    times = {b: ([], []) for b in binaries}
    stats = None
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "stats.json")
        for _ in range(runs):
            for b in binaries:
                subprocess.run(["cat", path], stdout=subprocess.DEVNULL, check=True)
                cmd = [b, "extract", path, "--iso", iso, "--iso", iso, "--runs", "1",
                       "--stats-json", out]
                subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
                with open(out) as f:
                    stats = json.load(f)
                times[b][0].append(stats[0]["seconds"])
                times[b][1].append(stats[1]["seconds"])
    cells, threads = stats[0]["file_cells"], stats[0]["threads"]
    for b in binaries:
        first, later = statistics.median(times[b][0]), statistics.median(times[b][1])
        rate = lambda s: cells / s / threads / 1e6
        print(f"{os.path.basename(b)} {os.path.basename(path)} iso {iso}: "
              f"first {first * 1e3:.2f} ms ({rate(first):.1f} M file cells/core-s), "
              f"later {later * 1e3:.2f} ms ({rate(later):.1f} M), active {stats[0]['active']}, "
              f"first runs (ms) {[round(t * 1e3, 1) for t in times[b][0]]}")


if __name__ == "__main__":
    main()
