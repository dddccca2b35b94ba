#!/usr/bin/env python3
"""A synthetic graphdeco PLY with SH degree 3 whose higher SH has structure, as trained SH does: each
Gaussian's 45 f_rest values a random mix of 8 fixed directions plus noise (0.02). Centres uniform in
[-1, 1]^3. Seeded: the same arguments write the same bytes. For SOG palette studies
(scripts/sog-palette-study.sh). Usage: low-rank-sh-model.py OUT.ply COUNT"""
import sys

import numpy as np


def main():
    out, n = sys.argv[1], int(sys.argv[2])
    rng = np.random.default_rng(7)
    d = 45
    names = ['x', 'y', 'z', 'nx', 'ny', 'nz', 'f_dc_0', 'f_dc_1', 'f_dc_2'] + ['f_rest_%d' % i for i in range(d)] + \
        ['opacity', 'scale_0', 'scale_1', 'scale_2', 'rot_0', 'rot_1', 'rot_2', 'rot_3']
    a = np.zeros((n, len(names)), np.float32)
    a[:, 0:3] = rng.uniform(-1, 1, (n, 3))
    a[:, 6:9] = rng.normal(0, 0.5, (n, 3))
    a[:, 9:9 + d] = rng.normal(0, 1, (n, 8)) @ rng.normal(0, 0.1, (8, d)) + rng.normal(0, 0.02, (n, d))
    a[:, 9 + d] = rng.normal(0, 2, n)
    a[:, 10 + d:13 + d] = rng.uniform(-6, -3, (n, 3))
    q = rng.normal(0, 1, (n, 4))
    a[:, 13 + d:17 + d] = q / np.linalg.norm(q, axis=1, keepdims=True)
    with open(out, 'wb') as f:
        f.write(('ply\nformat binary_little_endian 1.0\nelement vertex %d\n' % n +
                 ''.join('property float %s\n' % x for x in names) + 'end_header\n').encode())
        f.write(a.tobytes())


if __name__ == '__main__':
    main()
