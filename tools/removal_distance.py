#!/usr/bin/env python3
"""How far from the tool a cut removes its tets (README, "A coarse global solve with a fine
region around the tool").

Reads the fields of a run made with `esim run SCENARIO --no-video --fields 1` (RUN/fields/
frame_NNNNN.vtu, every frame) and, for each tet that leaves the alive set between two
frames, takes its centroid's distance to the tool's path point at the later frame. The path
is a straight segment travelled at constant speed (slab_cut's by default: x from -20 to +20
mm at y = 0, z = 9.5 mm, in 4 s at 30 fps). Prints the share within 1, 2, 4 and 6 mm, the
share more than 2 mm behind the tool along the path, and the median, p95 and largest
distance. Standard library only (no numpy).

Usage: tools/removal_distance.py RUN_DIR [--from X Y Z] [--to X Y Z] [--duration S] [--fps F]
"""
import argparse
import base64
import glob
import math
import os
import re
import struct
import sys

FORMATS = {'Float64': 'd', 'Float32': 'f', 'Int32': 'i', 'Int64': 'q', 'UInt8': 'B', 'UInt32': 'I'}


def arrays(path, names):
    """the named binary DataArrays of an ESim VTU (UInt64 header, base64, uncompressed)"""
    text = open(path).read()
    out = {}
    for m in re.finditer(r'<DataArray type="(\w+)" Name="(\w+)"[^>]*format="binary"[^>]*>'
                         r'\s*([^<]*)</DataArray>', text):
        kind, name, data = m.group(1), m.group(2), m.group(3).strip()
        if name not in names:
            continue
        raw = base64.b64decode(data)
        size = struct.unpack('<Q', raw[:8])[0]
        fmt = FORMATS[kind]
        out[name] = struct.unpack('<%d%s' % (size // struct.calcsize(fmt), fmt), raw[8:8 + size])
    missing = set(names) - set(out)
    if missing:
        sys.exit('removal_distance: %s: no binary DataArray %s (expected esim run --fields output)'
                 % (path, ', '.join(sorted(missing))))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('run_dir')
    ap.add_argument('--from', dest='start', type=float, nargs=3, default=[-0.02, 0, 0.0095])
    ap.add_argument('--to', dest='end', type=float, nargs=3, default=[0.02, 0, 0.0095])
    ap.add_argument('--duration', type=float, default=4.0, help='time along the path [s]')
    ap.add_argument('--fps', type=float, default=30.0)
    a = ap.parse_args()
    files = sorted(glob.glob(os.path.join(a.run_dir, 'fields', 'frame_*.vtu')))
    if len(files) < 2:
        sys.exit('removal_distance: %s: expected fields/frame_NNNNN.vtu for every frame '
                 '(esim run ... --fields 1)' % a.run_dir)
    first = arrays(files[0], {'Points', 'connectivity', 'tet_id'})
    p, c, ids = first['Points'], first['connectivity'], first['tet_id']
    centroid = {t: [sum(p[3 * c[4 * j + k] + ax] for k in range(4)) / 4 for ax in range(3)]
                for j, t in enumerate(ids)}
    direction = [e - s for s, e in zip(a.start, a.end)]
    length = math.sqrt(sum(d * d for d in direction))
    unit = [d / length for d in direction]
    alive, dist, behind = set(ids), [], 0
    for f in files[1:]:
        frame = int(re.search(r'frame_(\d+)\.vtu$', f).group(1))
        s = min(1.0, frame / a.fps / a.duration)
        tool = [st + s * d for st, d in zip(a.start, direction)]
        now = set(arrays(f, {'tet_id'})['tet_id'])
        for t in alive - now:
            x = centroid[t]
            dist.append(math.dist(x, tool))
            behind += sum((xi - ti) * ui for xi, ti, ui in zip(x, tool, unit)) < -2e-3
        alive = now
    if not dist:
        print('removal_distance: no tet removed in %d frames' % len(files))
        return
    n = len(dist)
    dist.sort()
    print('%d tets removed in %d frames' % (n, len(files)))
    for mm in (1, 2, 4, 6):
        print('within %d mm of the tool: %.1f %%' % (mm, 100.0 * sum(d < mm * 1e-3 for d in dist) / n))
    print('more than 2 mm behind it: %.1f %%' % (100.0 * behind / n))
    print('median %.2f mm, p95 %.2f mm, largest %.2f mm'
          % (1e3 * dist[n // 2], 1e3 * dist[int(0.95 * (n - 1))], 1e3 * dist[-1]))


if __name__ == '__main__':
    main()
