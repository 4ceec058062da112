#!/usr/bin/env python3
"""Issue 16 goal 3's second half on the clock: an occlusion query (shadow or AO ray) against a
primary ray, counted the same way on both sides.

    scripts/bench-occlusion.py BIN RUNS THREADS -- SCENE...

SCENE is what follows `amr-render` for the frame (a file, `--iso`, camera, `--size`). Each run
renders it twice in fresh processes, alternating which goes first: with the default shadows and
AO, and with `--no-shadows --ao 0`. The primary rays' cost is the bare frame's `render_ms` over
its rays; the occlusion queries' is the difference of the two frames' `render_ms` over the
difference of their `rays` (the queries, with their set-up and the AO filter counted in).
Prints the medians over RUNS (after one warm-up run) and the ratio (goal: at most 1).
"""
import json, os, statistics, subprocess, sys, tempfile


def render(binary, scene, extra, threads, tmp):
    out, stats = os.path.join(tmp, "f.exr"), os.path.join(tmp, "s.json")
    cmd = [f"{binary}/amr-render", *scene, *extra, "--threads", threads,
           "--exr-compression", "none", "-o", out, "--stats-json", stats]
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    with open(stats) as f:
        return json.load(f)


def main():
    if len(sys.argv) < 6 or sys.argv[4] != "--":
        sys.exit(__doc__)
    binary, runs, threads, scene = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[5:]
    variants = [("default", []), ("bare", ["--no-shadows", "--ao", "0"])]
    ms = {name: [] for name, _ in variants}
    last = {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(runs + 1):
            for name, extra in variants if r % 2 == 0 else variants[::-1]:
                s = render(binary, scene, extra, threads, tmp)
                if r > 0:
                    ms[name].append(s["render_ms"])
                last[name] = s
    med = {k: statistics.median(v) for k, v in ms.items()}
    primary = last["bare"]["rays"]
    queries = last["default"]["rays"] - primary
    pixels = last["bare"]["width"] * last["bare"]["height"]
    covered = last["bare"]["covered_pixels"]
    per_ray = med["bare"] * 1e3 / primary
    per_query = (med["default"] - med["bare"]) * 1e3 / queries
    print(f"{runs} runs, {threads} thread(s): {pixels} pixels, {covered} covered "
          f"({100 * covered / pixels:.1f} %); {primary} primary rays, {queries} queries")
    print(f"render_ms medians: default {med['default']:.1f}, --no-shadows --ao 0 {med['bare']:.1f}")
    cores = int(threads)
    print(f"primary ray {per_ray:.3f} us ({1 / per_ray / cores:.2f} M/s per core), occlusion "
          f"query {per_query:.3f} us ({1 / per_query / cores:.2f} M/s per core): "
          f"ratio {per_query / per_ray:.2f}")


if __name__ == "__main__":
    main()
