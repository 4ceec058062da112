#!/usr/bin/env python3
"""Issue 17's goal 1 over many isovalues: extraction rate per file cell of small-box files
against the same field on big boxes, isovalue by isovalue, for one or two builds.

    scripts/bench-extract-sweep.py [--files A,B,...] DATA RUNS THREADS ISOS BIN [BIN2]

DATA holds tiny.amrk, mid.amrk and big.amrk (the commands that make them are in
scripts/bench-pairs.py), or the files named by --files (without `.amrk`; `big` among them);
ISOS is a comma-separated list, e.g. 5,6,7,8,9,10,11,12. Each run extracts every file at every
isovalue once with each build in turn (alternating which goes first; the files of one isovalue
one after the other), in a fresh process, the page cache warm after a warm-up pass. Prints per
file and isovalue the median `seconds`, the rate in file cells per core-second, the ratio of `big`'s
rate to this file's (goal: at most 2) and the work counts (`active`, `boundary_evaluated`),
with BIN2's median over BIN's when two builds are given.

An isovalue where the surface stays inside the finest level costs one merged dual cell per
active cell; one where it crosses level boundaries evaluates boundary octants, whose corners
come from the sampler: the sweep shows both, where a single isovalue shows one.
"""
import json, os, statistics, subprocess, sys, tempfile

FILES = ["tiny", "mid", "big"]


def extract(binary, path, iso, threads, out):
    cmd = [f"{binary}/amr-render", "extract", path, "--iso", iso, "--threads", threads,
           "--stats-json", out]
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    with open(out) as f:
        return json.load(f)[0]


def main():
    global FILES
    if len(sys.argv) > 2 and sys.argv[1] == "--files":
        FILES = sys.argv[2].split(",")
        del sys.argv[1:3]
        if "big" not in FILES:
            sys.exit("--files must name big, the files' reference")
    if len(sys.argv) < 6:
        sys.exit(__doc__)
    data, runs, threads, isos = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4].split(",")
    bins = sys.argv[5:7]
    secs = {(b, f, i): [] for b in bins for f in FILES for i in isos}
    stats = {}
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "s.json")
        for f in FILES:
            subprocess.run(["cat", f"{data}/{f}.amrk"], stdout=subprocess.DEVNULL, check=True)
        for r in range(runs + 1):
            order = bins if r % 2 == 0 else bins[::-1]
            # The files of one isovalue run side by side, so the ratios compare runs close
            # in time.
            for i in isos:
                for f in FILES:
                    for b in order:
                        s = extract(b, f"{data}/{f}.amrk", i, threads, out)
                        if r > 0:
                            secs[(b, f, i)].append(s["seconds"])
                        stats[(b, f, i)] = s
    t = int(threads)
    print(f"{runs} runs, {threads} thread(s); rate = file cells per core-second (M); "
          "ratio = big's rate over this file's")
    head = "| file | iso | active | boundary | " + " | ".join(
        f"{os.path.basename(b)} ms | rate | ratio" for b in bins)
    print(head + (f" | {os.path.basename(bins[1])} / {os.path.basename(bins[0])} |" if len(bins) == 2 else " |"))
    print("|" + "---|" * (4 + 3 * len(bins) + (len(bins) == 2)))
    for f in FILES:
        for i in isos:
            row = []
            meds = []
            for b in bins:
                m = statistics.median(secs[(b, f, i)])
                big = statistics.median(secs[(b, "big", i)])
                cells, big_cells = stats[(b, f, i)]["file_cells"], stats[(b, "big", i)]["file_cells"]
                rate = cells / (m * t) / 1e6
                big_rate = big_cells / (big * t) / 1e6
                row.append(f"{m * 1e3:.1f} | {rate:.1f} | {big_rate / rate:.2f}")
                meds.append(m)
            s = stats[(bins[0], f, i)]
            line = f"| {f} | {i} | {s['active']} | {s['boundary_evaluated']} | " + " | ".join(row)
            if len(bins) == 2:
                line += f" | {meds[1] / meds[0]:.3f}"
            print(line + " |")


if __name__ == "__main__":
    main()
