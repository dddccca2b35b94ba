# 200 random Gaussians, SH degree 3, values inside what .spz can represent (see SpzReaderTest).
import random, struct, math
random.seed(11)
n, deg = 200, 3
rest = ((deg + 1) ** 2 - 1) * 3
names = ['x','y','z','nx','ny','nz','f_dc_0','f_dc_1','f_dc_2'] + ['f_rest_%d' % i for i in range(rest)] + \
        ['opacity','scale_0','scale_1','scale_2','rot_0','rot_1','rot_2','rot_3']
hdr = 'ply\nformat binary_little_endian 1.0\nelement vertex %d\n' % n + ''.join('property float %s\n' % s for s in names) + 'end_header\n'
body = b''
for i in range(n):
    q = [random.gauss(0, 1) for _ in range(4)]
    v = [random.uniform(-4, 4) for _ in range(3)] + [0, 0, 0] + [random.uniform(-3, 3) for _ in range(3)] + \
        [random.uniform(-0.9, 0.9) for _ in range(rest)] + [random.uniform(-6, 6)] + \
        [random.uniform(-8, 2) for _ in range(3)] + q
    body += struct.pack('<%df' % len(v), *v)
open('random200-sh3.ply', 'wb').write(hdr.encode() + body)
