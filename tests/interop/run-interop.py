#!/usr/bin/env python3
"""Interop tests against a real peer, PlayCanvas splat-transform (npm, the version package-lock.json
pins, installed by scripts/setup.sh into tests/interop/node_modules; nothing is fetched here).

For one format (--format) and two models (`splatwarp sample stripes --count 3000`, SH 1, and
make-sh3-model.py, 1000 random Gaussians with SH 3):
  ours -> theirs:  splatwarp convert model.ply x.FMT;  splat-transform x.FMT y.ply;  y vs model
  theirs -> ours:  splat-transform model.ply z.FMT;    splatwarp convert z.FMT w.ply; w vs model
Counts must be equal; every value must lie within the quantisation the format stores it with
(tolerances below, derived per format from docs/formats.md and the peer's code, per Gaussian where
the format's ranges are per chunk or per file). Formats that reorder (compressed PLY, SOG: Morton
order) are matched by position: each decoded Gaussian takes, among the source Gaussians within the
position tolerance box, the one whose worst error/tolerance ratio over all attributes is smallest; the
matching must be one to one. The other formats keep the order and are matched by index.
Where both decoders read the same file (ours -> theirs always; theirs -> ours for SOG, whose SH
palette error is the encoder's choice, not a bound of the format) the two decodes must also agree to
float32 arithmetic (REL and ANGLE_SLACK below).
--biker FILE instead decodes that .spz with both and requires the decodes to agree.
Exit 0 all within tolerance, 1 any failure, 77 skipped (no node, npm or installed splat-transform)."""
import argparse
import gzip
import json
import math
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
PEER_DIR = os.path.join(HERE, 'node_modules', '@playcanvas', 'splat-transform')
PEER_CLI = os.path.join(PEER_DIR, 'bin', 'cli.mjs')
SKIP = 77
C0 = 0.28209479177387814
# Float32 arithmetic in a decoder (lerps, exp/log, sqrt, divisions, then a float32 store): 2^-21
# relative to max(1, |v|), i.e. 4 to 8 units in the last place of a float32. Added to every
# quantisation bound, and alone the bound of two decoders reading the same file.
REL = 2.0 ** -21
# The same for a rotation angle (radians) between two decodes of one stored quaternion: the
# recomputed largest component and the normalisation, a few float32 ulps of unit components.
ANGLE_SLACK = 2.0 ** -19


def slack(v):
    return REL * max(1.0, abs(v)) if math.isfinite(v) else 0.0


# ---------------------------------------------------------------------------------------------
# PLY reading (binary little endian; graphdeco and compressed PLY elements)

PLY_TYPES = {'float': 'f', 'float32': 'f', 'double': 'd', 'float64': 'd', 'uchar': 'B', 'uint8': 'B',
             'char': 'b', 'int8': 'b', 'ushort': 'H', 'uint16': 'H', 'short': 'h', 'int16': 'h',
             'uint': 'I', 'uint32': 'I', 'int': 'i', 'int32': 'i'}


def read_ply_elements(path):
    """{element name: {property: tuple of values}} of a binary little-endian PLY, in file order."""
    data = open(path, 'rb').read()
    end = data.find(b'end_header\n')
    if not data.startswith(b'ply\n') or end < 0:
        raise RuntimeError('%s: not a PLY' % path)
    elements = []
    for line in data[:end].decode('ascii', 'replace').splitlines():
        p = line.split()
        if p[:1] == ['format'] and p[1] != 'binary_little_endian':
            raise RuntimeError('%s: PLY format %s (binary_little_endian expected)' % (path, p[1]))
        if p[:1] == ['element']:
            elements.append((p[1], int(p[2]), []))
        if p[:1] == ['property']:
            if p[1] == 'list':
                raise RuntimeError('%s: list property %s' % (path, p[-1]))
            elements[-1][2].append((p[2], PLY_TYPES[p[1]]))
    off = end + len('end_header\n')
    out = {}
    for name, count, props in elements:
        fmt = struct.Struct('<' + ''.join(t for _, t in props))
        rows = list(struct.iter_unpack(fmt.format, data[off:off + count * fmt.size]))
        if len(rows) != count:
            raise RuntimeError('%s: element %s truncated' % (path, name))
        off += count * fmt.size
        cols = list(zip(*rows)) if rows else [()] * len(props)
        out[name] = {pname: cols[k] for k, (pname, _) in enumerate(props)}
    return out


class Model:
    """A graphdeco model's columns: pos[3], logscale[3], fdc[3], opacity, rot[4] (w x y z), rest[3K]
    (f_rest_0.. in graphdeco order: channel-major, K = (degree+1)^2 - 1 coefficients a channel)."""

    def __init__(self, path):
        v = read_ply_elements(path).get('vertex')
        if v is None:
            raise RuntimeError('%s: no vertex element' % path)
        try:
            self.pos = [v[c] for c in 'xyz']
            self.logscale = [v['scale_%d' % a] for a in range(3)]
            self.fdc = [v['f_dc_%d' % c] for c in range(3)]
            self.opacity = v['opacity']
            self.rot = [v['rot_%d' % a] for a in range(4)]
        except KeyError as e:
            raise RuntimeError('%s: no property %s (not a graphdeco PLY)' % (path, e))
        nrest = sum(1 for k in v if k.startswith('f_rest_'))
        self.rest = [v['f_rest_%d' % k] for k in range(nrest)]
        self.k = nrest // 3
        self.degree = {0: 0, 3: 1, 8: 2, 15: 3}.get(self.k, -1)
        self.n = len(self.opacity)
        self.path = path


# Sign of each SH coefficient j = 1..15 (m = -l..l a band) under (x, y, z) -> (x, -y, -z): the parity
# in y and z of the basis monomials: y z x | xy yz 3z2-1 xz x2-y2 | y(3x2-y2) xyz y(5z2-1) z(5z2-3)
# x(5z2-1) z(x2-y2) x(x2-3y2).
FLIP_YZ_SH = [-1, -1, 1, -1, 1, 1, -1, 1, -1, 1, -1, -1, 1, -1, 1]


def flip_yz(m):
    """The model turned 180 degrees about x (y and z negated: RDF <-> RUB), exactly (signs only)."""
    neg = lambda col: tuple(-v for v in col)
    m.pos = [m.pos[0], neg(m.pos[1]), neg(m.pos[2])]
    m.rot = [m.rot[0], m.rot[1], neg(m.rot[2]), neg(m.rot[3])]
    m.rest = [neg(col) if FLIP_YZ_SH[k % m.k] < 0 else col for k, col in enumerate(m.rest)]
    return m


def sigmoid(x):
    if x != x:
        return x
    if x >= 0:
        return 1.0 / (1.0 + math.exp(-x))
    e = math.exp(x)
    return e / (1.0 + e)


def unit(q):
    n = math.sqrt(sum(c * c for c in q))
    return [c / n for c in q] if n > 0 else [1.0, 0.0, 0.0, 0.0]


def rot_angle(q, r):
    """Rotation angle (radians) between the rotations of two quaternions, q and -q alike: 4 asin(c/2)
    with c the chord between the unit quaternions (exactly 0 for equal inputs)."""
    a, b = unit(q), unit(r)
    c = min(math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b))), math.sqrt(sum((x + y) ** 2 for x, y in zip(a, b))))
    return 4.0 * math.asin(min(1.0, c / 2.0))


def smallest_three_angle(e):
    """Largest rotation angle (radians) when a unit quaternion is stored as its three smallest
    components, each within e, and the largest m (>= 1/2) is recomputed as sqrt(1 - sum): m moves by
    at most sum |a_i + a_i'| e / (m + m') <= 3 e (1 + e), so the chord c <= sqrt(3 e^2 + 9 e^2 (1+e)^2)
    and the angle is 4 asin(c / 2)."""
    c = math.sqrt(3 * e * e + 9 * e * e * (1 + e) ** 2)
    return 4.0 * math.asin(min(1.0, c / 2.0))


def band_of(j):
    """SH band of coefficient j (1-based within a channel's K)."""
    return 1 if j <= 3 else 2 if j <= 8 else 3


# ---------------------------------------------------------------------------------------------
# Tolerances: one class per format; each method gets the decoded index j (file order of the encoded
# file, for per-chunk ranges) and the source index i, and returns the largest allowed |error| (None:
# reported only).

class Tolerance:
    name = 'base'
    reorders = False

    def pos(self, src, j, i, a): return 0.0
    def logscale(self, src, j, i, a): return 0.0
    def fdc(self, src, j, i, c): return 0.0
    def alpha(self, src, j, i): return 0.0
    def rot(self, src, j, i): return 0.0
    def sh(self, src, j, i, k): return 0.0


class Exact(Tolerance):
    """graphdeco PLY: both sides read and write float32, nothing may change."""
    name = 'exact (float32 copied)'


class Agree(Tolerance):
    """Two decoders of one file: float32 arithmetic only (REL, ANGLE_SLACK)."""
    name = 'decoders agree'

    def pos(self, src, j, i, a): return slack(src.pos[a][i])
    def logscale(self, src, j, i, a): return slack(src.logscale[a][i])
    def fdc(self, src, j, i, c): return slack(src.fdc[c][i])
    def alpha(self, src, j, i): return REL
    def rot(self, src, j, i): return ANGLE_SLACK
    def sh(self, src, j, i, k): return slack(src.rest[k][i])


def spz_fractional_bits(path):
    """Byte 13 of the .spz header (v2/v3: inside the gzip stream; v4: the plain NGSP header)."""
    raw = open(path, 'rb').read()
    head = gzip.decompress(raw)[:16] if raw[:2] == b'\x1f\x8b' else raw[:16]
    if head[:4] != b'NGSP':
        raise RuntimeError('%s: no NGSP header' % path)
    return struct.unpack('<I', head[4:8])[0], head[13]


class Spz(Tolerance):
    """nianticlabs/spz packGaussians() (docs/formats.md 'Mapping'), rounding to nearest:
    centre: 24-bit fixed point with F fractional bits (header byte 13; 12 for these models): 2^-(F+1);
    log scale: u8 (s + 10) * 16: half a step, 1/32;
    colour: u8 f_dc * 0.15 * 255 + 127.5: half a step, 0.5 / (0.15 * 255) = 0.0131 in f_dc;
    alpha: u8 sigmoid * 255: 0.5 / 255;
    rotation (v3, v4): smallest three, 9-bit magnitude in units of sqrt(1/2) / 511: e = sqrt(1/2) / 1022
      per component, angle smallest_three_angle(e) = 0.27 degrees;
    SH: u8 x * 128 + 128 rounded, then to a bucket of 8 (band 1, 5 bits) or 16 (bands 2-3, 4 bits):
      (0.5 + 8/2) / 128 = 4.5/128 and (0.5 + 16/2) / 128 = 8.5/128."""

    def __init__(self, path):
        self.version, bits = spz_fractional_bits(path)
        self.pos_tol = 2.0 ** -(bits + 1)
        self.name = ('.spz v%d (centre 2^-%d, log scale 1/32, f_dc 0.0131, alpha 0.5/255, rot %.2f deg, '
                     'SH 4.5/128 8.5/128)' % (self.version, bits + 1,
                                              math.degrees(smallest_three_angle(math.sqrt(0.5) / 1022))))

    def pos(self, src, j, i, a): return self.pos_tol + slack(src.pos[a][i])
    def logscale(self, src, j, i, a): return 1 / 32 + slack(src.logscale[a][i])
    def fdc(self, src, j, i, c): return 0.5 / (0.15 * 255) + slack(src.fdc[c][i])
    def alpha(self, src, j, i): return 0.5 / 255 + REL
    def rot(self, src, j, i): return smallest_three_angle(math.sqrt(0.5) / 1022) + ANGLE_SLACK

    def sh(self, src, j, i, k):
        return (4.5 if band_of(k % src.k + 1) == 1 else 8.5) / 128 + slack(src.rest[k][i])


class CompressedPly(Tolerance):
    """SuperSplat compressed PLY (splat-transform CompressedChunk; docs/formats.md): per chunk of 256
    (in file order) float min/max of centres, log scales and colours 0.5 + C0 f_dc, read from the
    file's chunk element; packUnorm rounds, so half a code of the chunk's range:
    centre and log scale: 11, 10, 11 bits (x, y, z): range / (2^b - 1) / 2;
    colour: 8 bits of the colour range: range / 255 / 2 / C0 in f_dc; alpha: u8, 0.5 / 255;
    rotation: smallest three, 10 bits of a * sqrt(1/2) + 1/2: e = 0.5 / 1023 / sqrt(1/2) per component;
    SH: uchar trunc((f / 8 + 0.5) * 256), decoded at the code's centre: 4/256, except codes 0 and 255,
      which splat-transform decodes to -4 and 4: 8/256 for |f| > 4 - 8/256."""
    reorders = True
    BITS = (11, 10, 11)

    def __init__(self, path):
        ch = read_ply_elements(path)['chunk']
        self.chunks = [{k: ch[k][c] for k in ch} for c in range(len(ch['min_x']))]
        self.rot_e = 0.5 / 1023 / math.sqrt(0.5)
        self.name = 'compressed PLY (half a code of each chunk\'s range; rot %.2f deg; SH 4/256)' % math.degrees(
            smallest_three_angle(self.rot_e))

    def _half(self, j, lo, hi, bits):
        c = self.chunks[j // 256]
        return (c[hi] - c[lo]) / ((1 << bits) - 1) / 2

    def pos(self, src, j, i, a):
        ax = 'xyz'[a]
        return self._half(j, 'min_' + ax, 'max_' + ax, self.BITS[a]) + slack(src.pos[a][i])

    def logscale(self, src, j, i, a):
        ax = 'xyz'[a]
        return self._half(j, 'min_scale_' + ax, 'max_scale_' + ax, self.BITS[a]) + slack(src.logscale[a][i])

    def fdc(self, src, j, i, c):
        ch = 'rgb'[c]
        return self._half(j, 'min_' + ch, 'max_' + ch, 8) / C0 + slack(src.fdc[c][i])

    def alpha(self, src, j, i): return 0.5 / 255 + REL
    def rot(self, src, j, i): return smallest_three_angle(self.rot_e) + ANGLE_SLACK

    def sh(self, src, j, i, k):
        v = src.rest[k][i]
        return (8 if abs(v) > 4 - 8 / 256 else 4) / 256 + slack(v)


class Glb(Tolerance):
    """glTF KHR_gaussian_splatting, float32 (docs/formats.md): the 180-degree turn about Z only changes
    signs (exact); scale is stored linear, exp(s) rounded to float32 (relative 2^-24, i.e. 2^-24 in
    log s) and read back as a float32 log (2^-24 |s|); opacity stored as sigmoid in float32: 2^-24;
    rotation and SH copied (signs only)."""
    name = '.glb float32 (scale 2^-24 (1 + |s|), alpha 2^-24, rest exact)'

    def pos(self, src, j, i, a): return slack(src.pos[a][i])
    def logscale(self, src, j, i, a): return 2.0 ** -24 * (1 + abs(src.logscale[a][i])) + slack(src.logscale[a][i])
    def fdc(self, src, j, i, c): return slack(src.fdc[c][i])
    def alpha(self, src, j, i): return 2.0 ** -24 + REL
    def rot(self, src, j, i): return ANGLE_SLACK
    def sh(self, src, j, i, k): return slack(src.rest[k][i])


def sog_meta(path):
    with zipfile.ZipFile(path) as z:
        return json.loads(z.read('meta.json'))


class Sog(Tolerance):
    """PlayCanvas SOG v2 (meta.json + WebP in a zip; splat-transform writeSog):
    centre: v = sign(x) ln(|x| + 1) in 16 bits of [mins, maxs] (meta.json), truncated: one code
      D = (max - min) / 65535 in v; since dx/dv = e^|v| = |x| + 1, |dx| <= D (|x| + 1) e^D;
    log scale and f_dc: 256-entry 1-D k-means codebooks (meta.json scales / sh0), each value labelled
      with its nearest entry: the distance from the source value to the nearest codebook entry;
    alpha: u8 of sigmoid * 255, truncated: 1/255;
    rotation: smallest three, 8 bits of q sqrt(2) / 2 + 1/2, truncated: e = sqrt(2) / 255 per
      component, angle smallest_three_angle(e);
    higher SH: k-means palette of SH vectors (meta.json shN.count entries) then a 256-entry codebook:
      the palette error is the encoder's clustering, not a bound of the format: reported, not
      bounded here (the two decoders must agree on it instead)."""
    reorders = True

    def __init__(self, path):
        m = sog_meta(path)
        self.meta = m
        self.d = [(hi - lo) / 65535 for lo, hi in zip(m['means']['mins'], m['means']['maxs'])]
        self.scales = sorted(m['scales']['codebook'])
        self.colours = sorted(m['sh0']['codebook'])
        self.rot_e = math.sqrt(2) / 255
        self.name = ('SOG v%s, count %d (centre D (|x|+1) e^D, codebook distance, alpha 1/255, rot %.2f deg, '
                     'SH palette: reported)' % (m.get('version'), m.get('count', -1),
                                                math.degrees(smallest_three_angle(self.rot_e))))

    @staticmethod
    def _nearest(book, v):
        lo, hi = 0, len(book) - 1
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if book[mid] <= v:
                lo = mid
            else:
                hi = mid
        return min(abs(v - book[lo]), abs(v - book[hi]))

    def pos(self, src, j, i, a):
        x, d = src.pos[a][i], self.d[a]
        return d * (abs(x) + 1) * math.exp(d) + slack(x)

    def logscale(self, src, j, i, a):
        v = src.logscale[a][i]
        return self._nearest(self.scales, v) + slack(v)

    def fdc(self, src, j, i, c):
        v = src.fdc[c][i]
        return self._nearest(self.colours, v) + slack(v)

    def alpha(self, src, j, i): return 1 / 255 + REL
    def rot(self, src, j, i): return smallest_three_angle(self.rot_e) + ANGLE_SLACK
    def sh(self, src, j, i, k): return None


# ---------------------------------------------------------------------------------------------
# Comparison

ATTRS = ['pos', 'logscale', 'fdc', 'alpha', 'rot_deg', 'sh']


def pair_errors(src, dec, i, j, tol):
    """[(attribute, error, allowed or None)] for source Gaussian i against decoded Gaussian j."""
    out = []
    for a in range(3):
        out.append(('pos', abs(dec.pos[a][j] - src.pos[a][i]), tol.pos(src, j, i, a)))
    for a in range(3):
        out.append(('logscale', abs(dec.logscale[a][j] - src.logscale[a][i]), tol.logscale(src, j, i, a)))
    for c in range(3):
        out.append(('fdc', abs(dec.fdc[c][j] - src.fdc[c][i]), tol.fdc(src, j, i, c)))
    out.append(('alpha', abs(sigmoid(dec.opacity[j]) - sigmoid(src.opacity[i])), tol.alpha(src, j, i)))
    ang = rot_angle([src.rot[a][i] for a in range(4)], [dec.rot[a][j] for a in range(4)])
    t = tol.rot(src, j, i)
    out.append(('rot_deg', math.degrees(ang), None if t is None else math.degrees(t)))
    for k in range(min(len(src.rest), len(dec.rest))):
        out.append(('sh', abs(dec.rest[k][j] - src.rest[k][i]), tol.sh(src, j, i, k)))
    return out


def worst_ratio(errs):
    r = 0.0
    for _, e, t in errs:
        if t is None:
            continue
        if e != e:
            return math.inf
        if e > t:
            r = max(r, math.inf if t == 0 else e / t)
        elif t > 0:
            r = max(r, e / t)
    return r


def match_by_position(src, dec, tol, problems):
    """order[j] = source index of decoded Gaussian j (see the module docstring)."""
    # grid cells 4x the largest position tolerance (it varies with the decoded index for compressed
    # PLY's chunks, with the source value for SOG), so the 27 cells around a point hold its box
    cell = 1e-6
    for idx in range(dec.n):
        for a in range(3):
            cell = max(cell, tol.pos(src, idx, idx, a) * 4)
    grid = {}
    for i in range(src.n):
        key = tuple(int(math.floor(src.pos[a][i] / cell)) for a in range(3))
        grid.setdefault(key, []).append(i)
    order, used, misses = [], set(), 0
    for j in range(dec.n):
        p = [dec.pos[a][j] for a in range(3)]
        key = [int(math.floor(p[a] / cell)) for a in range(3)]
        cands = []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    cands += grid.get((key[0] + dx, key[1] + dy, key[2] + dz), [])
        cands = [i for i in cands if all(abs(p[a] - src.pos[a][i]) <= tol.pos(src, j, i, a) for a in range(3))]
        if not cands:
            misses += 1
            if misses > 50:
                problems.append('more than 50 decoded Gaussians have no source Gaussian within the position '
                                'tolerance: matching abandoned')
                return None
            cands = [min(range(src.n), key=lambda i: sum((p[a] - src.pos[a][i]) ** 2 for a in range(3)))]
        if len(cands) == 1:
            best = cands[0]
        else:  # within tolerance first, then not yet taken, then the smallest worst ratio
            ratio = {i: worst_ratio(pair_errors(src, dec, i, j, tol)) for i in cands}
            best = min(cands, key=lambda i: (ratio[i] > 1, i in used, ratio[i]))
        order.append(best)
        used.add(best)
    if misses:
        problems.append('%d decoded Gaussians have no source Gaussian within the position tolerance' % misses)
    if len(used) != dec.n:
        problems.append('matching by position is not one to one: %d decoded Gaussians took a source Gaussian '
                        'another had taken' % (dec.n - len(used)))
    return order


def compare(src, dec, tol, reorder=None):
    """Returns (stats {attr: [max, sum, count, max ratio]}, problems)."""
    problems = []
    if dec.n != src.n:
        problems.append('count %d, source %d' % (dec.n, src.n))
        return None, problems
    if dec.k != src.k:
        problems.append('%d f_rest coefficients a channel, source %d' % (dec.k, src.k))
    do_match = tol.reorders if reorder is None else reorder
    order = match_by_position(src, dec, tol, problems) if do_match else list(range(dec.n))
    if order is None:
        return None, problems
    stats = {a: [0.0, 0.0, 0, 0.0] for a in ATTRS}
    worst = {}
    for j in range(dec.n):
        for attr, e, t in pair_errors(src, dec, order[j], j, tol):
            s = stats[attr]
            if e != e:
                e = math.inf
            s[0] = max(s[0], e)
            s[1] += e
            s[2] += 1
            if t is not None:
                r = (math.inf if e > t else 0.0) if t <= 0 else e / t
                if r > s[3]:
                    s[3] = r
                    worst[attr] = (order[j], j, e, t)
    for attr in ATTRS:
        if stats[attr][3] > 1:
            i, j, e, t = worst[attr]
            problems.append('%s: error %.4g > allowed %.4g (source #%d, decoded #%d)' % (attr, e, t, i, j))
    return stats, problems


ROWS = []  # (model, comparison, stats, passed) for the table printed at the end


def report(model, title, tol_name, stats, problems):
    print('  %s, %s: %s' % (title, tol_name, 'ok' if not problems else 'FAIL'))
    for p in problems:
        print('    problem: ' + p)
    sys.stdout.flush()
    ROWS.append((model, title, stats, not problems))


def print_rows(heading):
    """The measured errors as a Markdown table: max / mean |error| an attribute, and the largest
    error / tolerance ratio over all bounded attributes."""
    print('\n%s\n' % heading)
    names = {'pos': 'centre', 'logscale': 'log scale', 'fdc': 'f_dc', 'alpha': 'alpha', 'rot_deg': 'rotation (deg)',
             'sh': 'higher SH'}
    print('| model | comparison | ' + ' | '.join(names[a] + ' max / mean' for a in ATTRS) + ' | max err/tol | |')
    print('|' + '---|' * (len(ATTRS) + 4))
    for model, title, stats, passed in ROWS:
        cells = []
        for a in ATTRS:
            mx, total, cnt, _ = stats[a] if stats else (0, 0, 0, 0)
            cells.append('%.3g / %.3g' % (mx, total / cnt) if cnt else '-')
        ratio = max(stats[a][3] for a in ATTRS) if stats else math.inf
        print('| %s | %s | %s | %.4f | %s |' % (model, title, ' | '.join(cells), ratio, 'ok' if passed else 'FAIL'))
    sys.stdout.flush()


# ---------------------------------------------------------------------------------------------
# Running the two programs

class Runner:
    def __init__(self, cli, tmp):
        self.cli, self.tmp, self.node = cli, tmp, shutil.which('node')
        self.seconds = {'splatwarp': 0.0, 'splat-transform': 0.0}

    def _run(self, who, argv):
        t = time.time()
        r = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=600)
        self.seconds[who] += time.time() - t
        if r.returncode != 0:
            out = r.stdout.decode('utf-8', 'replace').strip().splitlines()
            raise RuntimeError('%s exited %d: %s\n      %s' % (who, r.returncode, ' '.join(argv[-2:]),
                                                              '\n      '.join(out[-6:])))

    def ours(self, *args):
        self._run('splatwarp', [self.cli, '-q'] + list(args))

    def theirs(self, *args):
        self._run('splat-transform', [self.node, PEER_CLI, '-q', '-w'] + list(args))

    def path(self, name):
        return os.path.join(self.tmp, name)


# name: (extension, splatwarp flags, splat-transform flags, tolerance class, ours->theirs possible)
FORMATS = {
    'Ply': ('.ply', [], [], lambda path: Exact(), True),
    'CompressedPly': ('.compressed.ply', [], [], CompressedPly, True),
    'SpzV3': ('.spz', ['--spz-version', '3'], ['--spz-version', '3'], Spz, True),
    'SpzV4': ('.spz', ['--spz-version', '4'], ['--spz-version', '4'], Spz, True),
    # splat-transform 2.7.1 writes .glb but reads none: theirs -> ours only.
    'Glb': ('.glb', [], [], lambda path: Glb(), False),
    # SOG: its SH k-means runs on the CPU with -g cpu (no GPU adapter in CI).
    'Sog': ('.sog', [], ['-g', 'cpu'], Sog, True),
}


def spz_version_problems(fmt, path):
    if not fmt.startswith('Spz'):
        return []
    want, got = int(fmt[-1]), spz_fractional_bits(path)[0]
    return [] if got == want else ['%s is .spz version %d, %d asked for' % (os.path.basename(path), got, want)]


def check(model, title, ref, dec, tol, problems=(), reorder=None):
    """Compares the decoded model dec (a Model or a PLY path) with ref and reports it; True when
    within tolerance."""
    stats, p = compare(ref, dec if isinstance(dec, Model) else Model(dec), tol, reorder)
    p = list(problems) + p
    report(model, title, tol.name, stats, p)
    return not p


def run_format(fmt, run, models, peer_version):
    ext, our_flags, their_flags, tolerance, ours_to_theirs = FORMATS[fmt]
    # .spz axes: splatwarp stores a PLY's coordinates as they are (spz UNSPECIFIED, docs/formats.md), as
    # splat-transform 3.x does ("Decode is RAW (CoordinateSystem UNSPECIFIED)", its readSpz). 2.x
    # instead treats the file as RUB and PLY as RDF ("splat-transform treats SPZ as RDF on both sides
    # ... wasm flips RDF->RUB", its makeSpzPackOptions): its side of a .spz is ours turned 180 degrees
    # about x, an exact sign change, undone here on every decode of a file the other program wrote.
    flip = fmt.startswith('Spz') and int(peer_version.split('.')[0]) < 3
    conv = flip_yz if flip else (lambda m: m)
    if flip:
        print('%s: splat-transform %s stores .spz as RUB, splatwarp as the PLY (RDF): decodes across the two are '
              'compared turned back 180 degrees about x' % (fmt, peer_version))
    ok = True
    for label, model in models:
        src = Model(model)
        print('%s, model %s (%d Gaussians, SH degree %d)' % (fmt, label, src.n, src.degree))
        if not ours_to_theirs:
            print('  ours -> theirs: not possible (splat-transform reads no %s)' % ext)
        else:
            x, y, yo = (run.path(label + s) for s in ('.ours' + ext, '.ours.theirs.ply', '.ours.ours.ply'))
            try:
                run.ours('convert', model, x, *our_flags)
                run.theirs(x, y)
                ok &= check(label, 'ours -> theirs', src, conv(Model(y)), tolerance(x),
                            spz_version_problems(fmt, x))
                # the same file read by us: the two decoders must agree (file order, by index)
                run.ours('convert', x, yo)
                ok &= check(label, 'ours -> theirs, their decode vs ours of the same file', conv(Model(y)), yo,
                            Agree(), reorder=False)
            except RuntimeError as e:
                print('  ours -> theirs: FAIL: %s' % e)
                ROWS.append((label, 'ours -> theirs (did not run through)', None, False))
                ok = False
        z, w, zt = (run.path(label + s) for s in ('.theirs' + ext, '.theirs.ours.ply', '.theirs.theirs.ply'))
        try:
            run.theirs(*(their_flags + [model, z]))
            tol = tolerance(z)
            if fmt == 'Sog':
                # their own decode first: it documents their SOG (count, errors) before ours reads it
                run.theirs(z, zt)
                check(label, 'theirs -> theirs (splat-transform decodes its own file)', src, zt, tol)
            run.ours('convert', z, w)
            ok &= check(label, 'theirs -> ours', src, conv(Model(w)), tol, spz_version_problems(fmt, z))
            if fmt == 'Sog':
                ok &= check(label, 'theirs -> ours, their decode vs ours of the same file', Model(zt), w, Agree(),
                            reorder=False)
        except RuntimeError as e:
            print('  theirs -> ours: FAIL: %s' % e)
            ROWS.append((label, 'theirs -> ours (did not run through)', None, False))
            ok = False
    return ok


def run_biker(path, run, peer_version):
    """The engine's .spz decoded by both: same count, decodes agree (file order; turned back about x
    for splat-transform 2.x, see run_format)."""
    a, b = run.path('biker.theirs.ply'), run.path('biker.ours.ply')
    try:
        run.theirs(path, a)
        run.ours('convert', path, b)
        ta, tb = Model(a), Model(b)
        if int(peer_version.split('.')[0]) < 3:
            flip_yz(ta)
        print('%s: splat-transform decodes %d Gaussians (SH degree %d), splatwarp %d (SH degree %d)' % (
            os.path.basename(path), ta.n, ta.degree, tb.n, tb.degree))
        return check(os.path.basename(path), 'their decode vs ours', ta, b, Agree(), reorder=False)
    except RuntimeError as e:
        print('FAIL: %s' % e)
        return False


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--cli', required=True, help='the splatwarp CLI')
    ap.add_argument('--format', choices=sorted(FORMATS))
    ap.add_argument('--biker', help='a .spz both decode (skips when missing)')
    ap.add_argument('--keep', help='keep the files in this folder')
    a = ap.parse_args()
    if not a.format and not a.biker:
        ap.error('--format or --biker')
    for tool in ('node', 'npm'):
        if not shutil.which(tool):
            print('SKIP: %s is not installed (scripts/setup.sh installs node and npm)' % tool)
            return SKIP
    if not os.path.isfile(PEER_CLI):
        print('SKIP: %s is missing: run scripts/setup.sh (npm ci in tests/interop)' % PEER_CLI)
        return SKIP
    if a.biker and not os.path.isfile(a.biker):
        print('SKIP: %s is not there (the PlayCanvas engine\'s examples/assets/splats/biker.spz; not committed)'
              % a.biker)
        return SKIP
    version = json.load(open(os.path.join(PEER_DIR, 'package.json')))['version']
    node_version = subprocess.run([shutil.which('node'), '--version'], stdout=subprocess.PIPE).stdout.decode().strip()
    print('peer: @playcanvas/splat-transform %s on node %s' % (version, node_version))
    tmp = a.keep or tempfile.mkdtemp(prefix='splatwarp-interop-')
    os.makedirs(tmp, exist_ok=True)
    try:
        run = Runner(os.path.abspath(a.cli), tmp)
        if a.biker:
            ok = run_biker(a.biker, run, version)
        else:
            stripes, sh3 = run.path('stripes.ply'), run.path('random-sh3.ply')
            run.ours('sample', 'stripes', '--count', '3000', '-o', stripes)
            subprocess.run([sys.executable, os.path.join(HERE, 'make-sh3-model.py'), sh3, '--count', '1000',
                            '--seed', '30'], check=True)
            ok = run_format(a.format, run, [('stripes', stripes), ('random-sh3', sh3)], version)
        print_rows('%s through splat-transform %s (node %s)' % (a.format or 'biker', version, node_version))
        print('time: splatwarp %.1f s, splat-transform %.1f s' % (run.seconds['splatwarp'],
                                                                 run.seconds['splat-transform']))
        print('PASS' if ok else 'FAIL')
        return 0 if ok else 1
    finally:
        if not a.keep:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == '__main__':
    sys.exit(main())
