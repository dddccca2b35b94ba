#!/usr/bin/env python3
"""Precision loss of each model format (docs/formats.md): converts a PLY to each format with the
splatwarp CLI, back to PLY, and prints the largest and RMS differences against the source:
centre distance (also relative to the bounding-box diagonal; compressed PLY and SOG are compared
in the Morton order their writers store), DC colour
0.5 + C0 f_dc in 8-bit levels (as stored, and clamped to [0, 1] as a
viewer shows it), alpha, log scale, rotation angle (degrees), higher SH coefficients.
Usage: format-precision.py [--only FORMAT] SPLATWARP_CLI MODEL.ply [MODEL.ply ...]"""
import math, os, struct, subprocess, sys, tempfile

FORMATS = [('spz v3', '.spz', []), ('spz v4', '.spz', ['--spz-version', '4']), ('glb', '.glb', []),
           ('vdb points', '.vdb', ['--points']), ('compr. ply', '.compressed.ply', []), ('splat', '.splat', []), ('sog', '.sog', [])]
MORTON = ('.compressed.ply', '.sog')  # writers that store Gaussians in compressedPlyOrder()
C0 = 0.28209479177387814


def read_ply(path):
    """A graphdeco binary little-endian float PLY (as splatwarp writes) as a dict of columns."""
    data = open(path, 'rb').read()
    end = data.index(b'end_header\n') + len(b'end_header\n')
    names, n = [], 0
    for line in data[:end].decode().splitlines():
        p = line.split()
        if p[:2] == ['element', 'vertex']: n = int(p[2])
        if p[:1] == ['property']: names.append(p[2])
    vals = struct.unpack('<%df' % (n * len(names)), data[end:end + 4 * n * len(names)])
    k = len(names)
    return {name: vals[i::k] for i, name in enumerate(names)}, n


def morton_order(cols, n):
    """The order splatwarp's compressed PLY writer stores Gaussians in (compressedPlyOrder())."""
    def spread(v):
        out = 0
        for b in range(10):
            out |= ((v >> b) & 1) << (3 * b)
        return out
    lo = [min(cols[c]) for c in 'xyz']; hi = [max(cols[c]) for c in 'xyz']
    def norm(x, a):
        if x <= lo[a]: return 0.0
        if x >= hi[a]: return 1.0
        return 0.0 if hi[a] - lo[a] < 1e-5 else (x - lo[a]) / (hi[a] - lo[a])
    code = [sum(spread(int(min(1023.0, norm(cols[c][i], a) * 1024.0))) << (2 - a) for a, c in enumerate('xyz'))
            for i in range(n)]
    return sorted(range(n), key=lambda i: code[i])


def permuted(cols, order):
    return {k: [v[i] for i in order] for k, v in cols.items()}


def sigmoid(x): return 1 / (1 + math.exp(-x)) if x > -700 else 0.0


def compare(a, b, n):
    out = {}
    def stat(key, diffs):
        m = max(diffs) if diffs else 0.0
        rms = math.sqrt(sum(d * d for d in diffs) / len(diffs)) if diffs else 0.0
        out[key] = (m, rms)
    stat('pos', [math.sqrt(sum((a[c][i] - b[c][i]) ** 2 for c in 'xyz')) for i in range(n)])
    diag = math.sqrt(sum((max(a[c]) - min(a[c])) ** 2 for c in 'xyz')) or 1.0
    out['pos_bbox'] = (out['pos'][0] / diag, sum(math.sqrt(sum((a[c][i] - b[c][i]) ** 2 for c in 'xyz'))
                                                 for i in range(n)) / n / diag)
    stat('rgb', [max(abs(C0 * (a['f_dc_%d' % c][i] - b['f_dc_%d' % c][i])) for c in range(3)) * 255 for i in range(n)])
    clamp = lambda v: min(1.0, max(0.0, 0.5 + C0 * v))
    stat('rgb01', [max(abs(clamp(a['f_dc_%d' % c][i]) - clamp(b['f_dc_%d' % c][i])) for c in range(3)) * 255
                   for i in range(n)])
    stat('alpha', [abs(sigmoid(a['opacity'][i]) - sigmoid(b['opacity'][i])) for i in range(n)])
    stat('logscale', [max(abs(a['scale_%d' % c][i] - b['scale_%d' % c][i]) for c in range(3)) for i in range(n)])
    ang = []
    for i in range(n):
        q = [a['rot_%d' % c][i] for c in range(4)]; r = [b['rot_%d' % c][i] for c in range(4)]
        nq = math.sqrt(sum(x * x for x in q)); nr = math.sqrt(sum(x * x for x in r))
        d = min(1.0, abs(sum(x * y for x, y in zip(q, r))) / (nq * nr))
        ang.append(math.degrees(2 * math.acos(d)))
    stat('rot_deg', ang)
    rest = [k for k in a if k.startswith('f_rest_') and k in b]
    stat('sh_rest', [max((abs(a[k][i] - b[k][i]) for k in rest), default=0.0) for i in range(n)])
    return out


def main():
    args = sys.argv[1:]
    only = None
    if args[:1] == ['--only']:
        only, args = args[1], args[2:]
    cli, models = args[0], args[1:]
    with tempfile.TemporaryDirectory() as tmp:
        for model in models:
            src, n = read_ply(model)
            print('%s: %d Gaussians, %d bytes' % (os.path.basename(model), n, os.path.getsize(model)))
            print('  %-10s %9s %10s %10s %10s %10s %9s %9s %9s %10s %12s %9s %9s' % (
                'format', 'bytes', 'pos max', 'pos rms', 'max/diag', 'mean/diag', 'rgb max', 'rgb rms', 'rgb01 max',
                'alpha max', 'logscale max', 'rot max', 'sh max'))
            for name, ext, flags in FORMATS:
                if only and name != only:
                    continue
                out = os.path.join(tmp, 'm' + ext)
                subprocess.run([cli, '-q', 'convert', model, out] + flags, check=True)
                subprocess.run([cli, '-q', 'convert', out, os.path.join(tmp, 'back.ply')], check=True)
                back, m = read_ply(os.path.join(tmp, 'back.ply'))
                assert m == n, (name, m, n)
                ref = permuted(src, morton_order(src, n)) if ext in MORTON else src
                s = compare(ref, back, n)
                print('  %-10s %9d %10.3g %10.3g %10.3g %10.3g %9.3g %9.3g %9.3g %10.3g %12.3g %9.3g %9.3g' % (
                    name, os.path.getsize(out), s['pos'][0], s['pos'][1], s['pos_bbox'][0], s['pos_bbox'][1],
                    s['rgb'][0], s['rgb'][1], s['rgb01'][0],
                    s['alpha'][0], s['logscale'][0], s['rot_deg'][0], s['sh_rest'][0]))


if __name__ == '__main__':
    main()
