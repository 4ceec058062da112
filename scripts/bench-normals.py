#!/usr/bin/env python3
"""Smooth normals against flat ones, for two builds side by side (issue 16 goal 1).

    scripts/bench-normals.py BASE_BIN NEW_BIN RUNS THREADS -- SCENE...

BASE_BIN and NEW_BIN are directories holding an `amr-render` binary (the same one twice to
measure one build). SCENE is what follows `amr-render` for the frame (a file, `--iso`, camera,
`--size`). Each run renders the frame four times in fresh processes, `--no-shadows --ao 0`, with
smooth normals (the default) and with `--flat-normals` on each build, the order reversed every
other run. Prints the medians of `render_ms` over RUNS (after one warm-up run), smooth over flat
per build (goal: at most 1.3) and the new build's smooth frame over the base build's.
"""
import json, os, statistics, subprocess, sys, tempfile


def render(binary, scene, flat, threads, tmp):
    out, stats = os.path.join(tmp, "f.exr"), os.path.join(tmp, "s.json")
    cmd = [f"{binary}/amr-render", *scene, "--no-shadows", "--ao", "0", "--threads", threads,
           "--exr-compression", "none", "-o", out, "--stats-json", stats]
    if flat:
        cmd.append("--flat-normals")
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    with open(stats) as f:
        return json.load(f)["render_ms"]


def main():
    if len(sys.argv) < 7 or sys.argv[5] != "--":
        sys.exit(__doc__)
    bins = {"base": sys.argv[1], "new": sys.argv[2]}
    runs, threads, scene = int(sys.argv[3]), sys.argv[4], sys.argv[6:]
    variants = [(b, flat) for b in bins for flat in (False, True)]
    ms = {v: [] for v in variants}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(runs + 1):
            for b, flat in variants if r % 2 == 0 else variants[::-1]:
                t = render(bins[b], scene, flat, threads, tmp)
                if r > 0:
                    ms[(b, flat)].append(t)
    med = {v: statistics.median(x) for v, x in ms.items()}
    for b in bins:
        smooth, flat = med[(b, False)], med[(b, True)]
        print(f"{b}: smooth {smooth:.1f} ms, flat {flat:.1f} ms, smooth/flat {smooth / flat:.3f}")
    print(f"new/base, smooth: {med[('new', False)] / med[('base', False)]:.3f}")


if __name__ == "__main__":
    main()
