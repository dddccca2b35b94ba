#!/usr/bin/env python3
"""Per frame of an animate-study run (scripts/animate-study.sh): the judged Stage I/II field errors
of `anim` (and `other`, when present) from their manifests, and the frame-to-frame change: the mean
absolute change of every float in the PLY (all properties of all Gaussians) from the frame before.
Usage: animate-compare.py OUTDIR FIRST LAST"""
import array, json, os, sys


def floats(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    assert b"binary_little_endian" in data[:end] and b"property double" not in data[:end], path
    values = array.array("f")
    values.frombytes(data[end:])
    return values


def change(a, b):
    return sum(abs(x - y) for x, y in zip(a, b)) / len(a)


def main():
    out, first, last = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    runs = [r for r in ("anim", "other") if os.path.exists(os.path.join(out, r, "manifest.json"))]
    for run in runs:
        manifest = json.load(open(os.path.join(out, run, "manifest.json")))
        entries = {e["frame"]: e for e in manifest["entries"]}
        t = open(os.path.join(out, run + ".time")).read().split()
        print(f"{run}: CPU {float(t[0]) + float(t[1]):.1f} s")
        previous = None
        for f in range(first, last + 1):
            e = entries.get(f, {})
            err = e.get("fieldError", {})
            s1, s2 = err.get("stage1", {}), err.get("stage2", {})
            cur = floats(os.path.join(out, run, "frames", "deformed.%04d.ply" % f))
            d = change(cur, previous) if previous is not None else float("nan")
            previous = cur
            print(f"  frame {f}: opacity {s1.get('opacity', float('nan')):.4f} -> {s2.get('opacity', float('nan')):.4f}, "
                  f"color {s1.get('color', float('nan')):.4f} -> {s2.get('color', float('nan')):.4f}, "
                  f"change from previous {d:.5f}, {e.get('ms', 0) / 1000:.1f} s")


if __name__ == "__main__":
    main()
