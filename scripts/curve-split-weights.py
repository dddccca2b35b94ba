#!/usr/bin/env python3
"""Derive the curve split's children (src/deform/CurveSplit.h): three Gaussians of sigma
sqrt(1/2) (in units of the parent's sigma along the split axis) at offsets -d, 0, +d, amplitudes
w_outer, w_centre (times the parent's), chosen to minimise the L1 distance to the parent
exp(-x^2/2) relative to its mass. Plain Python (Nelder-Mead on a fine quadrature); prints the
constants and the L1 error, and the mass kept."""
import math

CHILD_SIGMA = math.sqrt(0.5)
XS = [i * 0.005 - 8.0 for i in range(3201)]
PARENT = [math.exp(-x * x / 2) for x in XS]
MASS = sum(PARENT)


def l1(params):
    d, wo, wc = params
    if d <= 0 or wo <= 0 or wc <= 0:
        return 1e9
    s2 = 2 * CHILD_SIGMA ** 2
    err = 0.0
    for x, p in zip(XS, PARENT):
        c = wc * math.exp(-x * x / s2) + wo * (math.exp(-(x - d) ** 2 / s2) + math.exp(-(x + d) ** 2 / s2))
        err += abs(p - c)
    return err / MASS


def nelder_mead(f, x0, step=0.1, iters=600):
    pts = [list(x0)] + [[x + (step if j == i else 0) for j, x in enumerate(x0)] for i in range(len(x0))]
    vals = [f(p) for p in pts]
    for _ in range(iters):
        order = sorted(range(len(pts)), key=lambda i: vals[i])
        pts, vals = [pts[i] for i in order], [vals[i] for i in order]
        centroid = [sum(p[j] for p in pts[:-1]) / (len(pts) - 1) for j in range(len(x0))]
        refl = [c + (c - w) for c, w in zip(centroid, pts[-1])]
        fr = f(refl)
        if fr < vals[0]:
            exp = [c + 2 * (c - w) for c, w in zip(centroid, pts[-1])]
            fe = f(exp)
            pts[-1], vals[-1] = (exp, fe) if fe < fr else (refl, fr)
        elif fr < vals[-2]:
            pts[-1], vals[-1] = refl, fr
        else:
            con = [c + 0.5 * (w - c) for c, w in zip(centroid, pts[-1])]
            fc = f(con)
            if fc < vals[-1]:
                pts[-1], vals[-1] = con, fc
            else:
                pts = [pts[0]] + [[b + 0.5 * (p - b) for b, p in zip(pts[0], q)] for q in pts[1:]]
                vals = [vals[0]] + [f(p) for p in pts[1:]]
    i = min(range(len(pts)), key=lambda i: vals[i])
    return pts[i], vals[i]


if __name__ == "__main__":
    best, err = nelder_mead(l1, [1.0, 0.3, 0.8])
    d, wo, wc = best
    mass = CHILD_SIGMA * (wc + 2 * wo)
    print(f"kCurveChildSigma = {CHILD_SIGMA:.8f}")
    print(f"kCurveOffset = {d:.4f}")
    print(f"kCurveOuterWeight = {wo:.4f}")
    print(f"kCurveCentreWeight = {wc:.4f}")
    print(f"L1 error / parent mass = {err:.4f}, children's mass / parent's = {mass:.4f}")
