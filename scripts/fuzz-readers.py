#!/usr/bin/env python3
"""Mutation fuzzing of amr-convert's readers on real dumps: each case copies a dump into a
scratch directory, mutates its text (AMReX `Header` and `Cell_H`, the `FAB` line before a box's
data in `Cell_D`; Enzo's parameter file, `.hierarchy` and `.boundary`) by random bytes, digits,
number tokens, deletions and truncations, converts it and fails on anything but exit 0 or 1, a
panic message or a conversion running past 30 s. Failing cases are kept under SCRATCH/bad-N.

    scripts/fuzz-readers.py amrex|fab|enzo DUMP SEED CASES [BIN]

DUMP: an AMReX plotfile directory (amrex, fab) or an Enzo dataset directory holding
`moving7_0010`-style files (enzo: the parameter file is the one without an extension).
BIN: the directory holding amr-convert (default target/release).
"""
import glob, os, random, shutil, subprocess, sys, tempfile

NUMBERS = [0, 1, 2, 3, 7, 8, 16, 64, 65, 2**31, 2**32 + 1, 2**63, -5]
TOKENS = [b"9", b"-", b"99999999999", b" ", b"\n", b"0", b"1e308", b"nan", b"-1", b"(", b")", b","]


def mutate(rng, data, lo=0, hi=None):
    hi = len(data) if hi is None else min(hi, len(data))
    for _ in range(rng.randint(1, 4)):
        if hi <= lo:
            break
        i = rng.randrange(lo, hi)
        kind = rng.randrange(5)
        if kind == 0:
            data[i] = rng.randrange(256)
        elif kind == 1:
            data[i:i + 1] = rng.choice(TOKENS)
        elif kind == 2:
            del data[i:i + rng.randint(1, 20)]
        elif kind == 3:
            j = i
            while j < len(data) and chr(data[j]).isdigit():
                j += 1
            data[i:j] = str(rng.choice(NUMBERS)).encode()
        elif lo == 0:
            del data[i:]
        hi = min(hi, len(data))


def main():
    if len(sys.argv) < 5:
        sys.exit(__doc__)
    mode, dump, seed, cases = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    binary = os.path.join(sys.argv[5] if len(sys.argv) > 5 else "target/release", "amr-convert")
    rng = random.Random(seed)
    scratch = tempfile.mkdtemp(prefix="fuzz-readers-")
    if mode == "amrex":
        targets = ["Header"] + [os.path.relpath(p, dump) for p in glob.glob(f"{dump}/Level_*/Cell_H")]
    elif mode == "fab":
        targets = [os.path.relpath(p, dump) for p in glob.glob(f"{dump}/Level_*/Cell_D_*")]
    elif mode == "enzo":
        names = os.listdir(dump)
        base = next(n for n in names if "." not in n)
        targets = [base, base + ".hierarchy", base + ".boundary"]
    else:
        sys.exit(f"unknown mode {mode}")
    bad = 0
    for case in range(cases):
        copy = os.path.join(scratch, "dump")
        shutil.rmtree(copy, ignore_errors=True)
        shutil.copytree(dump, copy)
        target = os.path.join(copy, rng.choice(targets))
        data = bytearray(open(target, "rb").read())
        if mode == "fab":
            starts = [i for i in range(len(data) - 3) if data[i:i + 3] == b"FAB"]
            s = rng.choice(starts)
            mutate(rng, data, s, s + 120)
        else:
            mutate(rng, data)
        open(target, "wb").write(bytes(data))
        source = copy if mode != "enzo" else os.path.join(copy, base)
        out = os.path.join(scratch, "out.amrk")
        try:
            r = subprocess.run([binary, source, "-o", out], capture_output=True, timeout=30)
            rc, err = r.returncode, r.stderr.decode(errors="replace")
        except subprocess.TimeoutExpired:
            rc, err = "timeout", ""
        if rc not in (0, 1) or "panicked" in err:
            bad += 1
            print(f"case {case}: {os.path.relpath(target, copy)}: exit {rc}\n{err[-800:]}")
            shutil.copytree(copy, os.path.join(scratch, f"bad-{case}"))
        if os.path.exists(out):
            os.remove(out)
    shutil.rmtree(os.path.join(scratch, "dump"), ignore_errors=True)
    if bad:
        print(f"{cases} cases, {bad} failures, kept in {scratch}")
    else:
        print(f"{cases} cases, 0 failures")
        shutil.rmtree(scratch, ignore_errors=True)
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
