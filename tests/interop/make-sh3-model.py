#!/usr/bin/env python3
"""A random graphdeco PLY with SH degree 3 for the interop tests (run-interop.py): seeded, so the same
arguments write the same bytes. Values stay inside what every compared format represents without
clamping: centres in [-4, 4] (.spz: +-2048 at 12 fractional bits), log scales in [-8, 1] (.spz:
[-10, 5.94]), f_dc in [-3, 3] (.spz: +-3.33), higher SH in [-0.9, 0.9] (.spz: [-1, 0.99],
compressed PLY: [-4, 4]), opacity logits in [-5, 5], quaternions Gaussian random (not unit, as
trainers write them).
Usage: make-sh3-model.py OUT.ply [--count N] [--seed S]"""
import argparse
import random
import struct


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('out')
    ap.add_argument('--count', type=int, default=1000)
    ap.add_argument('--seed', type=int, default=30)
    a = ap.parse_args()
    rng = random.Random(a.seed)
    rest = 15 * 3
    names = ['x', 'y', 'z', 'nx', 'ny', 'nz', 'f_dc_0', 'f_dc_1', 'f_dc_2'] + \
        ['f_rest_%d' % i for i in range(rest)] + ['opacity', 'scale_0', 'scale_1', 'scale_2'] + \
        ['rot_%d' % i for i in range(4)]
    header = 'ply\nformat binary_little_endian 1.0\nelement vertex %d\n' % a.count + \
        ''.join('property float %s\n' % s for s in names) + 'end_header\n'
    rec = struct.Struct('<%df' % len(names))
    body = bytearray()
    for _ in range(a.count):
        v = [rng.uniform(-4, 4) for _ in range(3)] + [0.0] * 3 + [rng.uniform(-3, 3) for _ in range(3)] + \
            [rng.uniform(-0.9, 0.9) for _ in range(rest)] + [rng.uniform(-5, 5)] + \
            [rng.uniform(-8, 1) for _ in range(3)] + [rng.gauss(0, 1) for _ in range(4)]
        body += rec.pack(*v)
    with open(a.out, 'wb') as f:
        f.write(header.encode() + bytes(body))


if __name__ == '__main__':
    main()
