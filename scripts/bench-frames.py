#!/usr/bin/env python3
"""Frames in one run against the same frames in separate runs (docs/benchmarks.md, issue 19).

usage: scripts/bench-frames.py OUTDIR [CELLS] [ORBIT_FRAMES] [SWEEP_FRAMES] [SERIES_STEPS]

Builds amr-render and amr-convert (release; or takes the binaries AMR_RENDER and AMR_CONVERT
name), writes a blobs file of CELLS cells (default 1e8)
into OUTDIR, and measures, with the file in the page cache:
- an orbit of ORBIT_FRAMES (36) frames in one run, against one run per frame with the same
  cameras (read back from the orbit's EXR headers);
- an isovalue sweep of SWEEP_FRAMES (20) frames in one run, against one run per isovalue;
- a time series of SERIES_STEPS (50) files (a smaller blobs case whose domain moves by 1/200 of
  its size per step) in one run: peak RSS (/usr/bin/time -v) against one step alone.
Prints a markdown table of wall times and peak RSS.
"""
import os
import re
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# AMR_RENDER and AMR_CONVERT name other binaries (then nothing is built).
RENDER = os.environ.get("AMR_RENDER", os.path.join(ROOT, "target", "release", "amr-render"))
CONVERT = os.environ.get("AMR_CONVERT", os.path.join(ROOT, "target", "release", "amr-convert"))
COMMON = ["--size", "512x384", "--ao", "1"]


def run(args):
    """Wall seconds and peak RSS (bytes) of one process."""
    t = time.perf_counter()
    p = subprocess.run(["/usr/bin/time", "-v"] + args, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if p.returncode != 0:
        sys.exit(f"failed: {' '.join(args)}\n{p.stderr}")
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr).group(1)) * 1024
    return wall, rss


def camera_of(exr):
    """The camera attribute an amr-render EXR records, as --camera-pos/--look-at/--up."""
    data = open(exr, "rb").read(1 << 16).decode("latin-1")
    m = re.search(r"pos=\[([^\]]*)\] look_at=\[([^\]]*)\] up=\[([^\]]*)\]", data)
    fmt = lambda s: ",".join(x.strip() for x in s.split(","))
    return ["--camera-pos", fmt(m.group(1)), "--look-at", fmt(m.group(2)), "--up", fmt(m.group(3))]


def warm(path):
    subprocess.run(["cat", path], stdout=subprocess.DEVNULL, check=True)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    out = sys.argv[1]
    cells = sys.argv[2] if len(sys.argv) > 2 else "1e8"
    n_orbit = int(sys.argv[3]) if len(sys.argv) > 3 else 36
    n_sweep = int(sys.argv[4]) if len(sys.argv) > 4 else 20
    n_series = int(sys.argv[5]) if len(sys.argv) > 5 else 50
    os.makedirs(out, exist_ok=True)
    if "AMR_RENDER" not in os.environ:
        subprocess.run(["cargo", "build", "--release", "-p", "amr-render", "-p", "amr-convert"],
                       cwd=ROOT, check=True)
    big = os.path.join(out, f"blobs-{cells}.amrk")
    if not os.path.exists(big):
        subprocess.run([CONVERT, "synth", "blobs", "-o", big, "--cells", cells], check=True)
    rows = []

    warm(big)
    orbit = os.path.join(out, "orbit.exr")
    one, _ = run([RENDER, big, "--iso", "10", "--orbit", str(n_orbit), "-o", orbit] + COMMON)
    sep = 0.0
    for k in range(n_orbit):
        frame = os.path.join(out, f"orbit_{k:04d}.exr")
        w, _ = run([RENDER, big, "--iso", "10", "-o", os.path.join(out, "alone.exr")]
                   + camera_of(frame) + COMMON)
        sep += w
    rows.append((f"{n_orbit}-frame orbit, iso 10", one, sep))

    warm(big)
    one, _ = run([RENDER, big, "--iso-sweep", f"8:16:{n_sweep}", "-o",
                  os.path.join(out, "sweep.exr")] + COMMON)
    sep = 0.0
    for k in range(n_sweep):
        iso = 8 + 8 * k / (n_sweep - 1)
        w, _ = run([RENDER, big, "--iso", repr(iso), "-o", os.path.join(out, "alone.exr")] + COMMON)
        sep += w
    rows.append((f"{n_sweep}-step isovalue sweep 8..16", one, sep))

    steps = []
    for k in range(n_series):
        path = os.path.join(out, f"step_{k:03d}.amrk")
        if not os.path.exists(path):
            subprocess.run([CONVERT, "synth", "blobs", "-o", path, "--cells", "1e7",
                            "--origin", f"{0.005 * k},0,0"], check=True, capture_output=True)
        steps.append(path)
    cam = ["--camera-pos", "1.9,-1.4,1.4", "--look-at", "0.6,0.5,0.5"]
    for s in steps:
        warm(s)
    series_wall, series_rss = run([RENDER] + steps + ["--iso", "10", "-o",
                                  os.path.join(out, "series.exr")] + cam + COMMON)
    one_wall, one_rss = run([RENDER, steps[0], "--iso", "10", "-o",
                             os.path.join(out, "alone.exr")] + cam + COMMON)

    print(f"| run | one run (s) | separate runs (s) | one / separate |")
    print(f"|---|---|---|---|")
    for name, a, b in rows:
        print(f"| {name} | {a:.2f} | {b:.2f} | {a / b:.3f} |")
    print()
    print(f"| time series | wall (s) | peak RSS (MB) |")
    print(f"|---|---|---|")
    print(f"| {n_series} steps of 1e7 cells in one run | {series_wall:.2f} | {series_rss / 1e6:.1f} |")
    print(f"| one step alone | {one_wall:.2f} | {one_rss / 1e6:.1f} |")
    print(f"\nseries peak RSS / one step: {series_rss / one_rss:.3f}")


if __name__ == "__main__":
    main()
