#!/usr/bin/env python3
"""Side-by-side render statistics of one or more amr-render binaries.

usage: scripts/bench-render-stats.py RUNS FILE.amrk ISO WxH BINARY [BINARY...]

For each run and each binary in turn (interleaved), the file is read into the page cache, then a
fresh process renders `BINARY FILE --iso ISO --size WxH -o OUT.exr --stats`. Prints, per binary,
the medians of the stage times (extraction, BVH build, frame), the peak RSS and the largest map
bytes found resident, as `--stats` reports them.
"""
import os
import statistics
import subprocess
import sys
import tempfile

KEYS = ["extract_ms", "bvh_ms", "render_ms", "peak_rss_bytes", "mapped_resident_peak_bytes"]


def main():
    if len(sys.argv) < 6:
        sys.exit(__doc__)
    runs, path, iso, size, binaries = (int(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4],
                                       sys.argv[5:])
    values = {b: {k: [] for k in KEYS} for b in binaries}
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "frame.exr")
        for _ in range(runs):
            for b in binaries:
                subprocess.run(["cat", path], stdout=subprocess.DEVNULL, check=True)
                cmd = [b, path, "--iso", iso, "--size", size, "-o", out, "--stats"]
                text = subprocess.run(cmd, capture_output=True, text=True, check=True)
                for line in (text.stdout + text.stderr).splitlines():
                    parts = line.split()
                    if len(parts) == 2 and parts[0] in KEYS:
                        values[b][parts[0]].append(float(parts[1]))
    for b in binaries:
        med = {k: statistics.median(v) for k, v in values[b].items() if v}
        print(f"{os.path.basename(b)} {os.path.basename(path)} iso {iso} {size}: "
              f"extract {med['extract_ms']:.0f} ms, BVH {med['bvh_ms']:.0f} ms, "
              f"frame {med['render_ms']:.0f} ms, peak RSS {med['peak_rss_bytes'] / 2**20:.0f} MiB, "
              f"map resident at most {med['mapped_resident_peak_bytes'] / 2**20:.0f} MiB "
              f"(runs: peak RSS MiB {[round(x / 2**20) for x in values[b]['peak_rss_bytes']]})")


if __name__ == "__main__":
    main()
