#!/usr/bin/env python3
"""Warm-start variants of an animate run against a cold reference, frame by frame: judged opacity
and colour field errors (the manifest's `fieldError.stage2`), their change relative to the cold
run, the frame-to-frame change (mean absolute change of every PLY float from the frame before),
Stage II's stop and kept iterations per frame (the manifest's `study` entry, when the run wrote one) and CPU time
(from RUN.time, `/usr/bin/time -f "%U %S %e"`).
Usage: animate-variants.py COLD_DIR VARIANT_DIR... (each DIR an animate output, DIR.time beside it)"""
import importlib.util, json, os, sys


# floats() and change() of animate-compare.py (a file name Python cannot import by name)
_spec = importlib.util.spec_from_file_location("animate_compare", os.path.join(os.path.dirname(__file__), "animate-compare.py"))
_compare = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_compare)
floats, change = _compare.floats, _compare.change


def rel(a, b):
    """a / b - 1 (0 where both are 0: frames where nothing moves)."""
    return a / b - 1 if b else (0.0 if a == 0 else float("inf"))


def load(run):
    manifest = json.load(open(os.path.join(run, "manifest.json")))
    frames = sorted(e["frame"] for e in manifest["entries"])
    errors = {e["frame"]: e["fieldError"]["stage2"] for e in manifest["entries"]}
    cpu = float("nan")
    if os.path.exists(run + ".time"):
        t = open(run + ".time").read().split()
        cpu = float(t[0]) + float(t[1])
    stops = [(e["study"]["stoppedAt"], e["study"]["bestIteration"]) for e in sorted(manifest["entries"], key=lambda e: e["frame"])
             if "study" in e]
    changes, previous = {}, None
    for f in frames:
        cur = floats(os.path.join(run, "frames", "deformed.%04d.ply" % f))
        if previous is not None:
            changes[f] = change(cur, previous)
        previous = cur
    return frames, errors, cpu, changes, stops


def main():
    cold = load(sys.argv[1])
    print(f"cold {sys.argv[1]}: CPU {cold[2]:.1f} s")
    for run in sys.argv[2:]:
        frames, errors, cpu, changes, stops = load(run)
        print(f"{run}: CPU {cpu:.1f} s ({cpu / cold[2]:.2f} of cold); Stage II (stopped at, kept): {stops}")
        worst = []
        for f in frames:
            o, c = errors[f]["opacity"], cold[1][f]["opacity"]
            if f != frames[0]:
                worst.append(rel(o, c))
            print(f"  frame {f}: opacity {o:.4f} (cold {c:.4f}, {100 * rel(o, c):+.1f}%), colour {errors[f]['color']:.4f} "
                  f"(cold {cold[1][f]['color']:.4f}), change {changes.get(f, float('nan')):.5f} (cold {cold[3].get(f, float('nan')):.5f})")
        warm = frames[1:]
        mo = sum(errors[f]["opacity"] for f in warm) / len(warm)
        mc = sum(cold[1][f]["opacity"] for f in warm) / len(warm)
        print(f"  frames {warm[0]}-{warm[-1]}: mean opacity {mo:.4f} vs cold {mc:.4f} ({100 * rel(mo, mc):+.2f}%), "
              f"worst frame {100 * max(worst):+.1f}%, change sum {sum(changes.values()):.5f} vs cold {sum(cold[3].values()):.5f}")


main()
