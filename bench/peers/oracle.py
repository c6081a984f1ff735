"""The distance benchmark's oracle: brute-force point–triangle distances in f64 over every
triangle, the generalised winding number, and a random sample of band voxels.

Everything is in voxel units on voxd's lattice (docs/methods.md, src/engine/snap.rs): a vertex
p goes to L = round-half-away((p − origin) · 256 / s) and sits at L / 256 voxels; voxel
(i, j, k)'s centre is (i + ½, j + ½, k + ½). These values are dyadic with few bits, so the
differences, cross products and dot products below are exact or within an ulp in f64: the
distance is exact to ~1e-15 relative, independent of voxd's integer code. World distance = that
· s.

No acceleration structure is trusted: triangles are grouped in chunks (spatially sorted) only to
skip a chunk whose bounding box is provably farther than a distance already found; every
triangle that could be nearer is evaluated.
"""
import numpy as np

FIXED_ONE = 256.0


def snap(V, origin, s):
    """voxd's snap (snap::to_lattice): lattice units, rounded half away from zero exactly as
    voxd does it (truncate, then +1 when the fraction is ≥ ½), returned in voxel units."""
    u = (np.asarray(V, np.float64) - np.asarray(origin, np.float64)) * (FIXED_ONE / s)
    a = np.abs(u)
    i = np.trunc(a)
    r = i + ((a - i) >= 0.5)
    return np.copysign(r, u) / FIXED_ONE


def world(Vv, origin, s):
    """Voxel-unit vertices back to world coordinates (what the peers are given)."""
    return np.asarray(origin, np.float64) + Vv * s


def seg_d2(P, A, B):
    """Squared distance from P to segments AB (broadcast)."""
    ab = B - A
    ap = P - A
    den = np.einsum("...i,...i->...", ab, ab)
    num = np.einsum("...i,...i->...", ap, ab)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(den > 0, np.clip(num / np.where(den > 0, den, 1), 0.0, 1.0), 0.0)
    q = ap - t[..., None] * ab
    return np.einsum("...i,...i->...", q, q)


def tri_d2(P, A, B, C):
    """Squared distance from point(s) P to triangles ABC: the minimum of the three edges and,
    where P projects inside a non-degenerate triangle, the plane distance. Degenerate (zero-area)
    triangles are their edges."""
    d = np.minimum(np.minimum(seg_d2(P, A, B), seg_d2(P, B, C)), seg_d2(P, C, A))
    n = np.cross(B - A, C - A)
    nn = np.einsum("...i,...i->...", n, n)
    s0 = np.einsum("...i,...i->...", n, np.cross(B - A, P - A))
    s1 = np.einsum("...i,...i->...", n, np.cross(C - B, P - B))
    s2 = np.einsum("...i,...i->...", n, np.cross(A - C, P - C))
    inside = (nn > 0) & (s0 >= 0) & (s1 >= 0) & (s2 >= 0)
    h = np.einsum("...i,...i->...", n, P - A)
    with np.errstate(invalid="ignore", divide="ignore"):
        plane = np.where(inside, h * h / np.where(nn > 0, nn, 1), np.inf)
    return np.minimum(d, plane)


class Oracle:
    """Exact unsigned distance (voxel units) from voxel centres to a snapped mesh."""

    def __init__(self, Vv, F, chunk=32):
        T = Vv[F]  # (m, 3, 3)
        c = T.mean(axis=1)
        lo, hi = c.min(axis=0), c.max(axis=0)
        q = ((c - lo) / np.maximum(hi - lo, 1e-30) * 1023).astype(np.int64)
        key = np.zeros(len(c), np.int64)
        for b in range(10):  # Morton order of the centroids
            for a in range(3):
                key |= ((q[:, a] >> b) & 1) << (3 * b + a)
        T = T[np.argsort(key, kind="stable")]
        m = len(T)
        pad = (-m) % chunk
        if pad:  # pad with copies of the last triangle (changes no minimum)
            T = np.concatenate([T, np.repeat(T[-1:], pad, axis=0)])
        self.T = T.reshape(-1, chunk, 3, 3)
        self.lo = self.T.min(axis=(1, 2))
        self.hi = self.T.max(axis=(1, 2))

    def d2(self, p):
        p = np.asarray(p, np.float64)
        g = np.maximum(np.maximum(self.lo - p, p - self.hi), 0.0)
        box = np.einsum("ij,ij->i", g, g)  # a lower bound for every triangle of the chunk
        first = int(np.argmin(box))
        t = self.T[first]
        ub = tri_d2(p, t[:, 0], t[:, 1], t[:, 2]).min()
        # Branch and bound: the chunks that could hold a nearer triangle, nearest box first, in
        # groups; stop when the next box is farther than the best distance found.
        cand = np.nonzero(box <= ub * (1 + 1e-9) + 1e-300)[0]
        cand = cand[np.argsort(box[cand], kind="stable")]
        for g0 in range(0, len(cand), 16):
            grp = cand[g0:g0 + 16]
            if box[grp[0]] > ub * (1 + 1e-9) + 1e-300:
                break
            t = self.T[grp].reshape(-1, 3, 3)
            ub = min(ub, tri_d2(p, t[:, 0], t[:, 1], t[:, 2]).min())
        return ub

    def distances(self, P):
        return np.sqrt(np.array([self.d2(p) for p in np.asarray(P, np.float64)]))


def winding_numbers(Vv, F, P, exact_max=200_000, margin=0.25, check=10, seed=0):
    """Generalised winding number (Jacobson et al. 2013) at P, and notes on how it was computed.

    Exact: the sum of signed solid angles over every triangle / 4π (igl.winding_number, the
    non-hierarchical sum; numpy's Van Oosterom–Strackee sum without libigl or for few points). That is 2·10⁹ solid
    angles for 2,000 points on a 1 M-triangle mesh, so above `exact_max` triangles every point is
    first screened with igl.fast_winding_number, and the exact sum is taken at every point whose
    fast value is within `margin` of ½ (where the fast value's error, ~1e-4, could matter) and at
    `check` random points, whose largest |fast − exact| is reported."""
    P = np.ascontiguousarray(P, np.float64)
    try:
        import igl
    except ImportError:
        return _wn_numpy(Vv, F, P), {"method": "exact (numpy)"}
    Vc, Fc = np.ascontiguousarray(Vv), np.ascontiguousarray(F, np.int64)

    def exact(Q):
        return np.asarray(igl.winding_number(Vc, Fc, np.ascontiguousarray(Q))).reshape(-1)

    if len(F) <= exact_max:
        return exact(P), {"method": "exact (igl.winding_number)"}
    w = np.asarray(igl.fast_winding_number(Vc, Fc, P)).reshape(-1)
    rng = np.random.default_rng(seed)
    pick = np.zeros(len(P), bool)
    pick[rng.choice(len(P), size=min(check, len(P)), replace=False)] = True
    near = np.abs(np.abs(w) - 0.5) < margin
    todo = pick | near
    # few points: this file's own sum (igl.winding_number has a fixed cost of ~20 s at 1 M triangles)
    we = _wn_numpy(Vv, F, P[todo]) if todo.sum() <= 200 else exact(P[todo])
    diff = float(np.abs(we - w[todo]).max()) if todo.any() else 0.0
    w[todo] = we
    return w, {"method": f"fast winding number, exact at {int(todo.sum())} points ({int(near.sum())} within "
                         f"{margin} of ½, {check} random: max |fast − exact| {diff:.1e})"}


def _wn_numpy(Vv, F, P, chunk=1 << 18):
    out = np.zeros(len(P))
    for k, p in enumerate(np.asarray(P, np.float64)):
        acc = 0.0
        for f0 in range(0, len(F), chunk):
            T = Vv[F[f0:f0 + chunk]] - p
            a, b, c = T[:, 0], T[:, 1], T[:, 2]
            la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
            num = np.einsum("ij,ij->i", a, np.cross(b, c))
            den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la
                   + np.einsum("ij,ij->i", c, a) * lb)
            acc += 2 * np.arctan2(num, den).sum()
        out[k] = acc / (4 * np.pi)
    return out


def sample_band(oracle, Vv, F, dims, band, n, seed):
    """n distinct voxels strictly inside the band (exact distance < band voxels, more than 1e-9
    from the boundary): a random point on a random triangle (area-weighted), moved by a random
    offset in the ball of radius `band`, taken to the voxel that contains it; kept when in the band.
    Every band voxel can be drawn (its centre is within `band` of some surface point); the draw
    follows surface area, not uniform over the band. Returns (indices (n, 3) int64, distances)."""
    rng = np.random.default_rng(seed)
    T = Vv[F]
    area = 0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1)
    prob = area / area.sum()
    dims = np.asarray(dims)
    got, dist, seen = [], [], set()
    tries = 0
    while len(got) < n and tries < 50 * n:
        m = 4 * (n - len(got)) + 16
        tries += m
        t = rng.choice(len(F), size=m, p=prob)
        r1, r2 = rng.random(m), rng.random(m)
        flip = r1 + r2 > 1
        r1[flip], r2[flip] = 1 - r1[flip], 1 - r2[flip]
        q = T[t, 0] + r1[:, None] * (T[t, 1] - T[t, 0]) + r2[:, None] * (T[t, 2] - T[t, 0])
        u = rng.normal(size=(m, 3))  # uniform in the ball of radius `band`
        u *= (band * rng.random(m) ** (1 / 3) / np.linalg.norm(u, axis=1))[:, None]
        q += u
        idx = np.floor(q).astype(np.int64)
        ok = np.all((idx >= 0) & (idx < dims), axis=1)
        for v in idx[ok]:
            key = tuple(int(x) for x in v)
            if key in seen:
                continue
            seen.add(key)
            d = float(np.sqrt(oracle.d2(v + 0.5)))
            if d < band - 1e-9:
                got.append(v)
                dist.append(d)
                if len(got) == n:
                    break
    return np.array(got, np.int64).reshape(-1, 3), np.array(dist)
