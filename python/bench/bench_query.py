"""Queries per second from Python: adwi vectorised, adwi one point per call, and scipy's
cKDTree with the paper's weights written in numpy (docs/method.md §3-§5).

    python python/bench/bench_query.py [--points 1000000] [--loop-points 10000]

Builds the default KR150-2 table (tables/kr150-2/samples.csv) in a temporary directory,
draws uniform random targets in the samples' box (as `tablec bench`'s "random in grid"),
and times, single-threaded:

- ``Table.query(points)``, served tier (the default) and exact tier, over all points;
- a Python loop calling ``Table.query(point)`` per point, over ``--loop-points`` points,
  extrapolated per second;
- ``cKDTree.query(actual positions, k, distance_upper_bound=ε)`` plus the approximation
  degrees, weights and prediction in numpy, checked against the exact tier.
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import adwi

REPO = Path(__file__).resolve().parents[2]
SAMPLES = REPO / "tables" / "kr150-2" / "samples.csv"
#: Offsets from the line through the origin below the tracker's resolution count as this
#: (docs/method.md §6).
MIN_PERPENDICULAR_OFFSET_MM = 1e-3


def best_of(repeats, f):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


def read_samples(path):
    with open(path) as f:
        comments = sum(1 for line in f if line.startswith("#"))
    data = np.genfromtxt(path, delimiter=",", names=True, skip_header=comments)
    nominal = np.column_stack([data["x"], data["y"], data["z"]])
    error = np.column_stack([data["dx"], data["dy"], data["dz"]])
    return nominal, error


class KdTreePaper:
    """The paper's method over a cKDTree of the samples' actual positions: the k nearest
    within ε (33), λ = sin φ / |s − p|, ζ = 1 / S with the area floor, q = ω1 λ^r / Σλ^r +
    ω2 ζ^r / Σζ^r, d_p = Σ q d. Defaults [λ] = [ζ] = 0, so (31), (32), (34) and (37) hold
    for every sample. The consistency screen (40) is checked; rows it would change are
    counted (none on this data, whose errors are 1-3 mm against ε/m = 25 mm)."""

    def __init__(self, nominal, error, method):
        from scipy.spatial import cKDTree

        self.actual = nominal + error
        self.error = error
        self.norm = np.linalg.norm(self.actual, axis=1)
        self.tree = cKDTree(self.actual)
        self.k = method["k"]
        self.radius = method["radius_mm"]
        self.w1, self.w2, self.r = method["w1"], method["w2"], method["power"]

    def predict(self, p):
        dist, idx = self.tree.query(p, k=self.k, distance_upper_bound=self.radius)
        found = np.isfinite(dist)  # (N, k); missing neighbours have index n
        idx = np.where(found, idx, 0)
        s = self.actual[idx]  # (N, k, 3)
        cross = np.linalg.norm(np.cross(s, p[:, None, :]), axis=2)
        p_norm = np.linalg.norm(p, axis=1)[:, None]
        s_norm = self.norm[idx]
        with np.errstate(divide="ignore", invalid="ignore"):
            sin_phi = np.minimum(cross / (s_norm * p_norm), 1.0)
            sin_phi = np.where(p_norm > 0, sin_phi, 0.0)
            lam = sin_phi / dist
            area = np.maximum(0.5 * cross, 0.5 * MIN_PERPENDICULAR_OFFSET_MM * np.maximum(p_norm, s_norm))
            zeta = 1.0 / area
        lam_r = np.where(found, lam**self.r, 0.0)
        zeta_r = np.where(found, zeta**self.r, 0.0)
        lam_sum = lam_r.sum(axis=1, keepdims=True)
        zeta_sum = zeta_r.sum(axis=1, keepdims=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            q = self.w1 * lam_r / lam_sum + self.w2 * zeta_r / zeta_sum
        d = self.error[idx]
        prediction = np.einsum("nk,nkj->nj", q, d)
        m = found.sum(axis=1)
        gaps = np.linalg.norm(prediction[:, None, :] - d, axis=2)
        screened = ((np.where(found, gaps, 0.0)).max(axis=1) > self.radius / np.maximum(m, 1))
        prediction[m == 0] = np.nan
        # Targets on a sample (distance 0) would take that sample's error alone (§6);
        # random targets never coincide with one.
        return prediction, m, int(screened.sum())


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--points", type=float, default=1e6)
    parser.add_argument("--loop-points", type=float, default=1e4)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    n, n_loop = int(args.points), int(args.loop_points)

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "kr150.tbl"
        report = adwi.build(SAMPLES, path, threads=1)
        table = adwi.Table.open(path)
        nominal, error = read_samples(SAMPLES)
        lo, hi = nominal.min(axis=0), nominal.max(axis=0)
        rng = np.random.default_rng(args.seed)
        points = rng.uniform(lo, hi, size=(n, 3))
        print(f"table: {report.samples} samples, {report.cells} cells of {report.cell_mm} mm, "
              f"{report.bytes} bytes; {n} random targets in the samples' box")

        t_served, served = best_of(args.repeats, lambda: table.query(points))
        t_exact, exact = best_of(args.repeats, lambda: table.query(points, exact=True))
        assert served.ok.all() and exact.ok.all()

        loop_points = points[:n_loop]

        def loop():
            out = np.empty((n_loop, 3))
            for i, p in enumerate(loop_points):
                out[i] = table.query(p).error_mm[0]
            return out

        t_loop, looped = best_of(args.repeats, loop)
        np.testing.assert_array_equal(looped, served.error_mm[:n_loop])

        rows = [
            ("adwi Table.query, vectorised, served tier", n, t_served),
            ("adwi Table.query, vectorised, exact tier", n, t_exact),
            ("adwi Table.query, Python loop, one point per call", n_loop, t_loop),
        ]
        try:
            kd = KdTreePaper(nominal, error, table.method)
        except ImportError:
            kd = None
            print("scipy is not installed: no cKDTree figures")
        if kd is not None:
            t_kd, (prediction, m, screened) = best_of(args.repeats, lambda: kd.predict(points))
            diff = np.abs(prediction - exact.error_mm).max()
            same_m = (m == exact.neighbours).mean()
            rows.append(("scipy cKDTree + paper's weights in numpy", n, t_kd))
            print(f"cKDTree vs exact tier: max |Δ| {diff:.2e} mm, same neighbour count "
                  f"{same_m:.4%}, rows the screen (40) would change: {screened}")

        print(f"{'contender':<52} {'points':>9} {'seconds':>9} {'queries/s':>12} {'ns/query':>9}")
        for name, count, seconds in rows:
            print(f"{name:<52} {count:>9} {seconds:>9.3f} {count / seconds:>12,.0f} "
                  f"{seconds / count * 1e9:>9.0f}")


if __name__ == "__main__":
    main()
