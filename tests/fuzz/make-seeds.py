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
# vdb_layout: the layout OpenVDB's io::File writes (format 224, grid offsets), with a few bytes of
# stand-in voxel data per grid: what checkVdbLayout() walks, and a file cut inside a grid.
def vstr(s): return struct.pack('<I', len(s)) + s
def vmeta(entries): return struct.pack('<I', len(entries)) + b''.join(vstr(n) + vstr(t) + struct.pack('<I', len(v)) + v for n, t, v in entries)
def vdb_file(grids):
    b = struct.pack('<qIIIb', 0x56444220, 224, 10, 0, 1) + b'0123abcd-0000-4000-8000-00000000beef'
    b += vmeta([(b'creator', b'string', b'splatwarp')]) + struct.pack('<i', len(grids))
    for name, typ in grids:
        desc = vstr(name) + vstr(typ) + vstr(b'')
        grid_pos = len(b) + len(desc) + 24
        head = struct.pack('<I', 2) + vmeta([(b'class', b'string', b'fog volume'), (b'file_voxel_count', b'int64', struct.pack('<q', 20))]) + vstr(b'UniformScaleMap') + bytes(40)
        block_pos = grid_pos + len(head)
        end_pos = block_pos + 16
        b += desc + struct.pack('<qqq', grid_pos, block_pos, end_pos) + head + bytes(range(16))
    return b
two = vdb_file([(b'density', b'Tree_float_5_4_3'), (b'color', b'Tree_vec3s_5_4_3')])
w('vdb_layout', 'two-grids.vdb', two)
w('vdb_layout', 'cut.vdb', two[:-5])
# picture_size: a PNG (signature, IHDR of 41x19 RGB, an empty IDAT, IEND) and a JPEG's headers
# (SOI, JFIF APP0, SOF0 of 41x19, a cut SOS), that JPEG with a 5,000-byte comment before its frame.
import zlib
def chunk(t, d): return struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d) & 0xffffffff)
png = b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', 41, 19, 8, 2, 0, 0, 0)) + chunk(b'IDAT', zlib.compress(bytes(19 * (1 + 41 * 3)))) + chunk(b'IEND', b'')
w('picture_size', 'rgb.png', png)
app0 = b'\xff\xe0' + struct.pack('>H', 16) + b'JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00'
sof = b'\xff\xc0' + struct.pack('>HBHHB', 17, 8, 19, 41, 3) + b'\x01\x11\x00\x02\x11\x01\x03\x11\x01'
sos = b'\xff\xda' + struct.pack('>HB', 12, 3) + b'\x01\x00\x02\x11\x03\x11\x00\x3f\x00'
w('picture_size', 'headers.jpg', b'\xff\xd8' + app0 + sof + sos + b'\xff\xd9')
w('picture_size', 'comment.jpg', b'\xff\xd8' + app0 + b'\xff\xfe' + struct.pack('>H', 5002) + b'c' * 5000 + sof + sos + b'\xff\xd9')
