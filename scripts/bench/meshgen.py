"""Generated meshes shared by the mesh benchmarks (scripts/bench/rays,
scripts/bench/bvh-quality): a bumpy UV sphere written as a binary STL."""
import numpy as np


def bumpy_sphere(n_tri):
    # UV sphere with n_lon = 2 n_lat, 2 n_lon (n_lat - 1) triangles.
    n_lat = max(4, int(round((n_tri / 4) ** 0.5)))
    n_lon = 2 * n_lat
    th = np.pi * np.arange(1, n_lat) / n_lat
    ph = 2 * np.pi * np.arange(n_lon) / n_lon
    T, P = np.meshgrid(th, ph, indexing="ij")
    r = 10 + 0.6 * np.sin(5 * P) * np.sin(4 * T) + 0.3 * np.cos(9 * T)
    v = np.stack([r * np.sin(T) * np.cos(P), r * np.sin(T) * np.sin(P), -r * np.cos(T)], -1).reshape(-1, 3)
    v = np.vstack([[0, 0, -10 - 0.3], v, [0, 0, 10 - 0.3]])
    ring = lambda i, j: 1 + (i - 1) * n_lon + (j % n_lon)
    top = len(v) - 1
    j = np.arange(n_lon)
    f = [np.stack([np.zeros(n_lon, int), ring(1, j + 1), ring(1, j)], -1),
         np.stack([np.full(n_lon, top), ring(n_lat - 1, j), ring(n_lat - 1, j + 1)], -1)]
    for i in range(1, n_lat - 1):
        a, b, c, d = ring(i, j), ring(i, j + 1), ring(i + 1, j + 1), ring(i + 1, j)
        f += [np.stack([a, b, c], -1), np.stack([a, c, d], -1)]
    return v, np.vstack(f)

def write_stl(path, v, f):
    tri = v[f].astype("<f4")
    rec = np.zeros(len(f), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tri
    with open(path, "wb") as fh:
        fh.write(b"generated bumpy sphere".ljust(80, b"\0"))
        fh.write(np.uint32(len(f)).tobytes())
        fh.write(rec.tobytes())
