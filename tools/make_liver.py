#!/usr/bin/python3
"""make_liver.py - generates assets/liver.obj, a liver-like closed organic surface.

Units: metres. Size: bounding box 0.160 x 0.100 x 0.070 m (x: right-left,
y: anterior-posterior, z: inferior-superior), centred at the origin.

Method (deterministic, numpy only):
  1. An implicit organ F(p) < 0 inside: a smooth union (soft-min, blend radius
     K_BLEND) of ellipsoids - the big right lobe, the tapering left lobe, the
     caudate bulge - evaluated in a gently bent frame (the visceral side is
     concave), minus a shallow notch (the gallbladder fossa / falciform notch).
  2. A geodesic icosphere of frequency N_FREQ (20 N^2 triangles) gives ray
     directions u. Along each ray from the origin F is sampled; the script asserts
     exactly one inside->outside crossing (the organ is star-shaped about the
     origin) and finds it by bisection: vertex = r(u) u. A few Laplacian passes
     on log r(u) over the sphere graph remove ray-grazing ripples.
  3. Because every vertex moves along its own ray and the organ is star-shaped,
     the surface is an embedding of the sphere: closed, manifold, outward
     counter-clockwise (icosphere order), and free of self-intersections.
  4. An axis scaling brings the bounding box to exactly the target size.
The script checks that every edge is used twice in opposite directions and that
the enclosed volume is positive, then writes the OBJ with 1e-7 m resolution.

Usage: tools/make_liver.py [-o assets/liver.obj]
"""
import argparse
import os
import sys

import numpy as np

N_FREQ = 20                                   # 20 * N^2 = 8000 triangles, 4002 vertices
TARGET_SIZE_M = np.array([0.160, 0.100, 0.070])
K_BLEND = 0.012                               # soft-min blend radius [m]
SMOOTH_ITERATIONS = 4                         # radial Laplacian smoothing passes

# ellipsoids: centre [m], semi-axes [m] (before the final exact rescaling)
LOBES = [
    ((0.030, 0.000, 0.000), (0.060, 0.050, 0.036)),    # right lobe (large)
    ((-0.035, -0.008, 0.006), (0.055, 0.036, 0.020)),  # left lobe (thin, tapering)
    ((-0.080, -0.012, 0.008), (0.020, 0.020, 0.010)),  # left lobe tip
    ((0.005, 0.025, -0.004), (0.022, 0.016, 0.018)),   # caudate bulge (posterior)
    ((0.050, -0.020, -0.012), (0.030, 0.028, 0.020)),  # inferior right bulge
]
NOTCH = ((0.000, -0.065, -0.004), (0.012, 0.028, 0.030))  # anterior notch (subtracted)


def ellipsoid_distance(p, centre, axes):
    """approximate signed distance to an ellipsoid [m] (negative inside)"""
    q = (p - np.asarray(centre)) / np.asarray(axes)
    return (np.linalg.norm(q, axis=-1) - 1.0) * np.min(axes)


def organ_field(p):
    """F(p) < 0 inside the organ; p has shape (..., 3) in metres"""
    # bent frame: the inferior (visceral) side curves up toward the middle
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    bent = np.stack([x, y, z - 4.0 * x * x + 0.005 * np.sin(40.0 * y)], axis=-1)
    d = np.stack([ellipsoid_distance(bent, c, a) for c, a in LOBES], axis=-1)
    blob = -K_BLEND * np.log(np.sum(np.exp(-d / K_BLEND), axis=-1))  # soft-min
    notch = ellipsoid_distance(bent, *NOTCH)
    k = 0.004
    return k * np.log(np.exp(blob / k) + np.exp(-notch / k))  # soft-max(blob, -notch)


def geodesic_sphere(n):
    """frequency-n geodesic icosphere: unit vertices, outward CCW triangles"""
    t = (1.0 + 5.0 ** 0.5) / 2.0
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
                 dtype=float)
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts, index, tris = [], {}, []

    def vid(a, b, c, i, j):
        # canonical key: barycentric weights on the sorted corner ids (shared edges agree)
        w = {a: n - i - j, b: i, c: j}
        key = tuple(sorted((k, wk) for k, wk in w.items() if wk != 0))
        if key not in index:
            p = sum(v[k] * wk for k, wk in key) / n
            index[key] = len(verts)
            verts.append(p / np.linalg.norm(p))
        return index[key]

    for a, b, c in faces:
        for i in range(n):
            for j in range(n - i):
                p0, p1, p2 = vid(a, b, c, i, j), vid(a, b, c, i + 1, j), vid(a, b, c, i, j + 1)
                tris.append((p0, p1, p2))
                if i + j < n - 1:
                    p3 = vid(a, b, c, i + 1, j + 1)
                    tris.append((p1, p3, p2))
    return np.array(verts), np.array(tris, dtype=np.int64)


def radial_surface(dirs, r_max=0.2, samples=800, bisections=60):
    """r(u): the single crossing of organ_field along each ray (asserts star-shape)"""
    r = np.linspace(0.0, r_max, samples)
    f = organ_field(dirs[:, None, :] * r[None, :, None])
    inside = f < 0
    assert inside[:, 0].all(), "origin must be inside the organ"
    crossings = np.sum(inside[:, :-1] != inside[:, 1:], axis=1)
    assert (crossings == 1).all(), f"organ not star-shaped: {np.sum(crossings != 1)} rays"
    k = np.argmax(~inside, axis=1)
    lo, hi = r[k - 1], r[k]
    for _ in range(bisections):
        mid = 0.5 * (lo + hi)
        fin = organ_field(dirs * mid[:, None]) < 0
        lo, hi = np.where(fin, mid, lo), np.where(fin, hi, mid)
    return 0.5 * (lo + hi)


def smooth_radii(r, tris, iterations=SMOOTH_ITERATIONS, weight=0.5):
    """Laplacian smoothing of log r over the sphere graph (stays star-shaped)"""
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    count = np.bincount(e[:, 0], minlength=len(r))
    log_r = np.log(r)
    for _ in range(iterations):
        mean = np.bincount(e[:, 0], weights=log_r[e[:, 1]], minlength=len(r)) / count
        log_r = (1.0 - weight) * log_r + weight * mean
    return np.exp(log_r)


def check_closed_oriented(tris):
    """every directed edge once, and its reverse once"""
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    directed = set(map(tuple, e))
    assert len(directed) == len(e), "a directed edge repeats (inconsistent orientation)"
    assert all((b, a) in directed for a, b in directed), "open surface"


def enclosed_volume(v, tris):
    a, b, c = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
    return np.sum(np.einsum("ij,ij->i", a, np.cross(b, c))) / 6.0


def write_obj(path, v, tris, header):
    with open(path, "w") as out:
        for line in header:
            out.write("# " + line + "\n")
        for p in v:
            out.write("v %.7f %.7f %.7f\n" % (p[0], p[1], p[2]))
        for t in tris:
            out.write("f %d %d %d\n" % (t[0] + 1, t[1] + 1, t[2] + 1))


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", default=os.path.join(root, "assets", "liver.obj"))
    args = ap.parse_args()

    # 1-3. rays, crossings, surface
    dirs, tris = geodesic_sphere(N_FREQ)
    v = dirs * smooth_radii(radial_surface(dirs), tris)[:, None]
    # 4. exact bounding box, centred
    lo, hi = v.min(axis=0), v.max(axis=0)
    v = (v - 0.5 * (lo + hi)) * (TARGET_SIZE_M / (hi - lo))
    # rescaling about a point inside keeps the star shape; recentring moves the
    # centre, which is harmless: the embedding is preserved by any affine map
    v = np.round(v, 7)
    check_closed_oriented(tris)
    vol = enclosed_volume(v, tris)
    assert vol > 0, "surface must be oriented outward"
    header = ["liver-like closed surface generated by tools/make_liver.py (do not edit)",
              "units: metres; bounding box %.3f x %.3f x %.3f m, centred at the origin"
              % tuple(TARGET_SIZE_M),
              "%d vertices, %d triangles, outward counter-clockwise, enclosed volume %.6e m^3"
              % (len(v), len(tris), vol)]
    os.makedirs(os.path.dirname(args.output), exist_ok=True)
    write_obj(args.output, v, tris, header)
    print("%s: %d vertices, %d triangles, volume %.4e m^3, bbox %s m"
          % (args.output, len(v), len(tris), vol, np.round(v.max(0) - v.min(0), 4)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
