#!/usr/bin/env python3
"""The curve shift's share (src/deform/CurveSplit.h curveShifted()): one Gaussian of unit sigma
along its axis a and sigma s across it, bent by phi's second-order term into the banana
y = h a^2 + noise, against one Gaussian moved across by share * h (the banana's mean is h).
Prints the L1 distance (relative to the mass) per bend b = h / s and share; the L1 depends on b
only. Plain Python, a midpoint quadrature on [-5, 5] x [-6 s, 6 s + 25 h]."""
import math

SHARES = [0.0, 0.25, 0.45, 0.5, 0.75, 1.0]


def l1(bend, share, n=240):
    s, h = 1.0, bend
    xs = [-5 + 10 * (i + 0.5) / n for i in range(n)]
    lo, hi = -6 * s, 6 * s + 25 * h
    ys = [lo + (hi - lo) * (j + 0.5) / n for j in range(n)]
    area = (10 / n) * ((hi - lo) / n)
    c = 1 / (2 * math.pi * s)
    total = 0.0
    for a in xs:
        ga = c * math.exp(-0.5 * a * a)
        for y in ys:
            banana = ga * math.exp(-0.5 * ((y - h * a * a) / s) ** 2)
            gauss = ga * math.exp(-0.5 * ((y - share * h) / s) ** 2)
            total += abs(banana - gauss)
    return total * area


if __name__ == "__main__":
    print("bend  " + "  ".join(f"share {x:<4}" for x in SHARES) + "  best")
    for bend in [0.05, 0.1, 0.2, 0.35, 0.5, 1.0, 1.5, 2.0]:
        row = [l1(bend, x) for x in SHARES]
        best = SHARES[min(range(len(row)), key=row.__getitem__)]
        print(f"{bend:<5} " + "  ".join(f"{v:10.4f}" for v in row) + f"  {best}")
