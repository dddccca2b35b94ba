# Seed corpora of the fuzz targets (see README.md): python3 make-seeds.py corpus
import random, struct, os, sys
random.seed(5)
out = sys.argv[1]
def ply(n, deg, fmt='binary_little_endian', typ='float', normals=True):
    rest = ((deg + 1) ** 2 - 1) * 3
    names = ['x','y','z'] + (['nx','ny','nz'] if normals else []) + ['f_dc_0','f_dc_1','f_dc_2'] + \
            ['f_rest_%d' % i for i in range(rest)] + ['opacity','scale_0','scale_1','scale_2','rot_0','rot_1','rot_2','rot_3']
    h = 'ply\nformat %s 1.0\nelement vertex %d\n' % (fmt, n) + ''.join('property %s %s\n' % (typ, s) for s in names) + 'end_header\n'
    b = h.encode()
    code = {'float': 'f', 'double': 'd'}[typ]
    e = '<' if fmt == 'binary_little_endian' else '>'
    for i in range(n):
        v = [round(random.uniform(-2, 2), 3) for _ in names]
        if fmt == 'ascii': b += (' '.join(str(x) for x in v) + '\n').encode()
        else: b += struct.pack(e + code * len(v), *v)
    return b
def w(d, name, data):
    os.makedirs(os.path.join(out, d), exist_ok=True)
    open(os.path.join(out, d, name), 'wb').write(data)
for d in ('ply', 'ply_header'):
    w(d, 'le-sh0.ply', ply(3, 0))
    w(d, 'ascii-sh1.ply', ply(2, 1, 'ascii'))
    w(d, 'be-double-nonormals.ply', ply(2, 0, 'binary_big_endian', 'double', False))
w('ply_header', 'extra-element.ply', b'ply\nformat ascii 1.0\ncomment x\nelement vertex 1\nproperty float x\nproperty uchar foo\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n1 2\n3 0 1 2\n')
rec = b''
for i in range(4):
    rec += struct.pack('<6f', *[random.uniform(-2, 2) for _ in range(3)], *[random.uniform(0.001, 0.1) for _ in range(3)])
    rec += bytes([random.randrange(256) for _ in range(4)]) + bytes([255, 128, 128, 128])
w('splat', 'four.splat', rec)
open(os.path.join(out, '..', 'tiny8.ply'), 'wb').write(ply(8, 1))
# 4 Gaussians, SH 3, all values in [-0.9, 0.9] (source of the .spz seeds)
random.seed(3)
names = ['x', 'y', 'z', 'f_dc_0', 'f_dc_1', 'f_dc_2'] + ['f_rest_%d' % i for i in range(45)] + \
        ['opacity', 'scale_0', 'scale_1', 'scale_2', 'rot_0', 'rot_1', 'rot_2', 'rot_3']
b = ('ply\nformat binary_little_endian 1.0\nelement vertex 4\n' + ''.join('property float %s\n' % s for s in names) +
     'end_header\n').encode()
for i in range(4):
    b += struct.pack('<%df' % len(names), *[random.uniform(-0.9, 0.9) for _ in names])
open(os.path.join(out, '..', 'tiny4-sh3.ply'), 'wb').write(b)
