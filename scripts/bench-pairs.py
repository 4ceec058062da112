#!/usr/bin/env python3
"""Two builds side by side in alternated pairs: one JSON line per run (wall time, peak RSS and
the run's own `--stats-json` figures), for medians and paired ratios (`--summary`).

    scripts/bench-pairs.py DATA START_BIN END_BIN OUT.jsonl PAIRS [CASE,...]
    scripts/bench-pairs.py --summary OUT.jsonl [REGEX]

DATA holds the files the cases read, made by
    amr-bench boxes --base 18 --ratios 2,4,2 --sizes 2,4 -o tiny.amrk
    amr-bench boxes --base 16 --ratios 2,4,2 --sizes 2,16 -o mid.amrk
    amr-bench boxes --base 16 --ratios 2,4,2 --sizes 16,16 -o big.amrk
    amr-bench boxes --base 16 --ratios 2,4,2 --sizes 16,16 --pieces 2,4 -o big-p2-4.amrk
    amr-convert synth blobs -o b1m.amrk --cells 1.2e6 --levels 4
    amr-convert synth blobs --levels 3 --ratio 2 --base 32 --brick 16 -o demo.amrk
    amr-convert synth blobs --cells 1e8 -o b1e8v2.amrk
    amr-convert synth blobs --cells 1e9 -o b1e9.amrk
START_BIN and END_BIN are folders holding `amr-render` and `amr-bench`. Each pair runs every case
once with each build, the builds' order alternating from pair to pair, after one warm-up run
of each (the page cache warm). Needs /usr/bin/time and taskset (Linux).
"""
import json, os, re, statistics, subprocess, sys, tempfile, time
from collections import defaultdict

D = sys.argv.pop(1) if len(sys.argv) > 1 and sys.argv[1] != "--summary" else "."
C = f"{D}/b1m.amrk --iso 10 --camera-pos 0.55,0.45,0.85 --look-at 0.5,0.5,0.5 --size 1024x768"
DEMO = f"{D}/demo.amrk --iso 10:#d99e59 --iso 6:#598cd9:0.3 --outline boxes --size 1024x768"
T = tempfile.mkdtemp(prefix="bench-pairs-")
CASES = {
    "closeup_flat": ("render", f"{C} --no-shadows --ao 0 --flat-normals"),
    "closeup_smooth": ("render", f"{C} --no-shadows --ao 0"),
    "closeup_default": ("render", C),
    "demo": ("render", DEMO),
    "e8_smooth": ("render", f"{D}/b1e8v2.amrk --iso 10 --size 1024x768 --no-shadows --ao 0"),
    "e8_default": ("render", f"{D}/b1e8v2.amrk --iso 10 --size 1024x768"),
    "e9_sweep": ("render", f"{D}/b1e9.amrk --iso-sweep 20:10:2 --size 512x384"),
    "demo_orbit12": ("render", f"{DEMO} --orbit 12"),
    "tiny_extract": ("extract", f"extract {D}/tiny.amrk --iso 10"),
    "mid_extract": ("extract", f"extract {D}/mid.amrk --iso 10"),
    "big_extract": ("extract", f"extract {D}/big.amrk --iso 10"),
    "p24_extract5": ("extract", f"extract {D}/big-p2-4.amrk --iso 5"),
    "p24_extract12": ("extract", f"extract {D}/big-p2-4.amrk --iso 12"),
    "big_extract5": ("extract", f"extract {D}/big.amrk --iso 5"),
    "big_extract12": ("extract", f"extract {D}/big.amrk --iso 12"),
    "tiny_extract_t1": ("extract", f"extract {D}/tiny.amrk --iso 10 --threads 1"),
    "mid_extract_t1": ("extract", f"extract {D}/mid.amrk --iso 10 --threads 1"),
    "big_extract_t1": ("extract", f"extract {D}/big.amrk --iso 10 --threads 1"),
    "tiny_extract6_t1": ("extract", f"extract {D}/tiny.amrk --iso 6 --threads 1"),
    "mid_extract6_t1": ("extract", f"extract {D}/mid.amrk --iso 6 --threads 1"),
    "big_extract6_t1": ("extract", f"extract {D}/big.amrk --iso 6 --threads 1"),
    "tiny_info": ("plain", f"info {D}/tiny.amrk"),
    "sample": ("sample", f"sample {D}/b1m.amrk --methods octant --runs 5"),
}
DEFAULT = ["closeup_flat", "closeup_smooth", "closeup_default", "demo", "e8_smooth", "e8_default",
           "e9_sweep", "tiny_extract", "big_extract", "tiny_extract_t1", "big_extract_t1", "sample"]

def run(binary, case):
    kind, args = CASES[case]
    j = f"{T}/j.json"
    if os.path.exists(j):
        os.remove(j)
    if kind == "sample":
        cmd = ["taskset", "-c", "1", f"{binary}/amr-bench"] + args.split()
    else:
        cmd = [f"{binary}/amr-render"] + args.split()
        if kind == "render":
            cmd += ["-o", f"{T}/x.exr", "--stats-json", j]
        elif kind == "extract":
            cmd += ["--stats-json", j]
    cmd = ["/usr/bin/time", "-f", "TIME %e %M"] + cmd
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"{case} failed: {p.stderr[-2000:]}")
    m = re.search(r"TIME (\S+) (\d+)", p.stderr)
    rec = {"wall_s": float(m.group(1)), "peak_rss_kb": int(m.group(2))}
    if kind == "render":
        frames = json.load(open(j))
        frames = frames if isinstance(frames, list) else [frames]
        f = frames[-1]
        if case == "e9_sweep":
            rec.update(extract_ms=f["extract_ms"], bvh_ms=f["bvh_ms"], render_ms=f["render_ms"],
                       first_extract_ms=frames[0]["extract_ms"])
        elif case == "demo_orbit12":
            rs = sorted(x["render_ms"] for x in frames[1:])
            rec.update(render_ms_median=rs[len(rs) // 2], render_ms_sum=sum(x["render_ms"] for x in frames))
        else:
            rec.update(render_ms=f["render_ms"], extract_ms=f["extract_ms"], bvh_ms=f["bvh_ms"],
                       rays=f["rays"])
    elif kind == "extract":
        e = json.load(open(j)); e = e[0] if isinstance(e, list) else e
        rec.update(seconds=e["seconds"], mcells_per_core_s=e["cells_per_core_second"] / 1e6)
    elif kind == "sample":
        for line in p.stdout.splitlines():
            mm = re.match(r"\|\s*octant\s*\|\s*(near|away)\s*\|\s*(\d+)\s*\|\s*(\d+)", line)
            if mm:
                rec[f"{mm.group(1)}_fresh_ns"] = int(mm.group(2))
                rec[f"{mm.group(1)}_scratch_ns"] = int(mm.group(3))
    return rec

def main():
    start, end, out, pairs = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
    cases = sys.argv[5].split(",") if len(sys.argv) > 5 else DEFAULT
    with open(out, "a") as fo:
        for c in cases:  # warm-up, page cache
            run(start, c); run(end, c)
        for i in range(pairs):
            for c in cases:
                order = [("start", start), ("end", end)] if i % 2 == 0 else [("end", end), ("start", start)]
                for name, b in order:
                    rec = run(b, c)
                    rec.update(pair=i, case=c, bin=name, load=os.getloadavg()[0], t=time.time())
                    fo.write(json.dumps(rec) + "\n"); fo.flush()
            print(f"pair {i} done", flush=True)

def summary(path, rx=None):
    """Per case and figure: the medians, the median of the per-pair ratios end/start, and the
    pairs in which the end was lower."""
    rx = re.compile(rx) if rx else None
    runs = defaultdict(dict)
    cases = []
    for line in open(path):
        r = json.loads(line)
        runs[(r["case"], r["pair"])][r["bin"]] = r
        if r["case"] not in cases:
            cases.append(r["case"])
    for c in cases:
        prs = [v for (cc, _), v in sorted(runs.items()) if cc == c and "start" in v and "end" in v]
        if not prs:
            continue
        loads = [v[b]["load"] for v in prs for b in ("start", "end")]
        print(f"{c}: {len(prs)} pairs, load {min(loads):.2f}-{max(loads):.2f}")
        for k, x in prs[0]["start"].items():
            if k in ("pair", "case", "bin", "t", "load") or not isinstance(x, (int, float)):
                continue
            if rx and not rx.search(k):
                continue
            s = [v["start"][k] for v in prs]
            e = [v["end"][k] for v in prs]
            ratios = [b / a for a, b in zip(s, e) if a]
            lower = sum(1 for a, b in zip(s, e) if b < a)
            ratio = statistics.median(ratios) if ratios else float("nan")
            print(f"  {k:22s} start {statistics.median(s):12.3f}  end {statistics.median(e):12.3f}"
                  f"  ratio {ratio:.3f}  end lower {lower}/{len(prs)}")


if sys.argv[1] == "--summary":
    summary(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else None)
else:
    main()
