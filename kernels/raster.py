"""Tiled soft-silhouette rasterizer of convex prisms (``docs/architecture.md``, "Rasterizer").

Per frame f and primitive k (a convex prism projected to 2D vertices), :func:`build_hulls`
finds the convex hull of the projected vertices (Jarvis march), its edge lines and screen
bounds padded by the soft band. :func:`rasterize` cuts the image into TILE x TILE tiles, each
drawn by :func:`lanes` threads taking every lanes-th row of it (one on the CPU, a thread per row
on a GPU); a thread sorts the primitives into out of reach, fully covered, or partial over its
tile (keeping only the hull edges that can matter in the tile), sorts the partial ones again
per row, and writes, per pixel centre p = (j + 0.5, i + 0.5):

    sd_k = max over hull edges e of n_e . p - o_e       signed distance [px], n_e outward
    c_k  = sigmoid(-sd_k / sigma)                       exactly 0 (1) beyond +(-) CUTOFF sigma
    z_k  = max over faces with n . r < 0 of d / n . r   entry depth [m] of the ray r through p,
                                                        or through the nearest hull point
                                                        where sd_k > 0 (continuous depth)
    v_k  = c_k prod_{l: z_l < z_k} (1 - c_l)            visible mask; depth only where two
                                                        or more layers cover p

:func:`rasterize` writes v_k, or only what the mask losses read of it (the profiles: row
sums, column sums and the overlap sum v_k t_k with a target mask), and keeps the layers of
each pixel that two or more primitives cover: the bit mask of those primitives, their
coverages c_k and their depths z_k; and where a primitive's soft band is (|sd_k| <= CUTOFF
sigma), which primitives are partial in each tile, the band's pixels per row as a bit mask,
and at them c_k and the edge of sd_k. :func:`rasterize_backward` visits, per tile and
primitive (its rows shared by threads likewise), only those band pixels, reads c_k there and
the other layers kept at the pixel, turns dL/dv (given, or from the profiles' gradients:
dL/dv_ij = g_row_i + g_col_j + g_overlap t_ij) into dL/dsd_k and reduces, per hull edge e, the
moments (sum g, sum g (p - a_e)) over the pixels whose distance edge is e (a_e the edge's first
vertex), which give the gradients of the edge's two vertices in closed form, added atomically
per (thread, primitive, edge). Depth order carries no gradient. All kernels are forward-only.
"""

import functools
from typing import Any

import warp as wp

from . import OPTIMIZATION_LEVEL

_OPTIONS = {"enable_backward": False, "optimization_level": OPTIMIZATION_LEVEL}
wp.set_module_options(_OPTIONS)

TILE = 16
"""Tile edge [px]."""

MAX_PRIMITIVES = 8
"""Most primitives per frame (bits of a tile's primitive mask)."""

MAX_SIDES = 24
"""Most sides of a prism: 2 * MAX_SIDES vertices, MAX_SIDES + 2 face planes."""

MAX_HULL = 32
"""Most hull vertices (a convex n-prism's silhouette has at most n + 2)."""

CUTOFF = 8.0
"""Coverage is exactly 0 where sd > CUTOFF * sigma and 1 where sd < -CUTOFF * sigma. The tail
dropped, sigmoid(-8) = 3.4e-4 of a pixel, is a tenth of the masks' 8-bit step (1/255), so
the cut costs no precision the targets have, while a narrow band leaves fewer partial pixels
to shade and differentiate (docs/results-history.md has the timings)."""

MITER_CAP = 4.0
"""Bounds pad the hull by CUTOFF * sigma times the largest corner miter, capped here."""

_EMPTY_BOUND = wp.constant(wp.vec4(1.0e30, 1.0e30, -1.0e30, -1.0e30))
_ALL_BITS = wp.constant(wp.uint32(0xFFFFFFFF))  # typed: a bare literal is emitted as an int32 that overflows
_LAYERS = wp.types.vector(length=MAX_PRIMITIVES, dtype=wp.float32)  # a value per primitive at a pixel
_EDGES = wp.types.vector(length=MAX_PRIMITIVES, dtype=wp.int32)  # a hull edge per primitive at a pixel
_EDGE_SETS = wp.types.vector(length=MAX_PRIMITIVES, dtype=wp.uint32)  # hull edges (bit e) per primitive in a tile
_ROW_VALUES = wp.types.matrix(shape=(MAX_PRIMITIVES, TILE), dtype=wp.float32)  # per primitive along a tile row
_ROW_EDGES = wp.types.matrix(shape=(MAX_PRIMITIVES, TILE), dtype=wp.int32)
_ROW_BITS = wp.types.vector(length=TILE, dtype=wp.int32)  # a primitive bit mask per pixel of a tile row
_MOMENTS = wp.types.matrix(shape=(MAX_HULL, 3), dtype=wp.float32)  # (sum g, sum g p) per hull edge


@wp.struct
class Outlines:
    """Per frame f and primitive k, the prisms as the raster draws them: ``visible`` (F, P) int32
    (0: not drawn), projected ``vertices`` (F, P, V) [px], and what :func:`build_hulls` makes of
    them: ``hull`` (F, P, MAX_HULL) int32 hull vertex indices, counter-clockwise, ``count`` (F, P)
    int32 hull sizes (0: not drawn), edge ``line``s (F, P, MAX_HULL) (unit outward normal,
    offset) and screen ``bound``s (F, P) (u0, v0, u1, v1) [px] padded by the soft band; and the
    face planes (n, d) in camera coordinates, camera-facing first: ``plane`` (F, P, MAX_SIDES +
    2) and ``plane_count`` (F, P) int32 of those facing the camera."""

    visible: wp.array2d(dtype=int)
    vertices: wp.array3d(dtype=wp.vec2)
    hull: wp.array3d(dtype=int)
    count: wp.array2d(dtype=int)
    line: wp.array3d(dtype=wp.vec3)
    bound: wp.array2d(dtype=wp.vec4)
    plane_count: wp.array2d(dtype=int)
    plane: wp.array3d(dtype=wp.vec4)


@wp.struct
class Layers:
    """What :func:`rasterize` keeps for :func:`rasterize_backward`: where any primitive covers a
    pixel, the bit mask ``covered`` (F, H, W) int32 of those that do; where two or more do, their
    coverages ``coverage`` (F, P, H, W) and depths ``depth`` (F, P, H, W) [m] (as far as their
    order needs, :func:`_depths`); per tile, the bit mask ``tiles`` (F, H / TILE, W / TILE) int32
    of the primitives partial there; per row of a tile and primitive partial in the tile, the bit
    mask ``band`` (F, P, H, W / TILE) int32 of its pixels (bit j - x0) in the soft band, and at
    those pixels its coverage ``band_coverage`` (F, P, H, W) and the hull ``edge`` (F, P, H, W)
    int32 its signed distance is measured to. A call writes all that the backward pass reads back
    (elsewhere the buffers hold older calls' values), so they need no clearing."""

    covered: wp.array3d(dtype=int)
    coverage: wp.array4d(dtype=float)
    depth: wp.array4d(dtype=float)
    tiles: wp.array3d(dtype=int)
    band: wp.array4d(dtype=int)
    band_coverage: wp.array4d(dtype=float)
    edge: wp.array4d(dtype=wp.int32)


@wp.struct
class Profiles:
    """What the mask losses read of the visible masks v against the target masks t (T, P, H, W) ``target``, read
    at each rendered frame's index ``frame`` (F,) into them: row sums ``rows`` (F, P, H), column sums ``cols``
    (F, P, W) and overlaps sum_ij v t ``overlap`` (F, P); or the gradients of those sums (with the same targets)."""

    frame: wp.array(dtype=int)
    target: wp.array4d(dtype=float)
    rows: wp.array3d(dtype=float)
    cols: wp.array3d(dtype=float)
    overlap: wp.array2d(dtype=float)


@wp.func
def _cross(a: wp.vec2, b: wp.vec2) -> float:
    return a[0] * b[1] - a[1] * b[0]


@wp.func
def _lowest(bits: Any) -> int:
    """Index of the lowest set bit of a nonzero integer (iterate with bits &= bits - 1)."""
    one = type(bits)(1)
    return int(wp.bit_count((bits ^ (bits & (bits - one))) - one))


@wp.func
def _hull_step(vert_in: wp.array3d(dtype=wp.vec2), f: int, k: int, n: int, cur: int) -> int:
    """Jarvis step: the vertex after ``cur`` counter-clockwise (-1 when all coincide)."""
    pc = vert_in[f, k, cur]
    nxt = int(-1)
    e = wp.vec2(0.0, 0.0)
    ee = float(0.0)
    for q in range(n):
        d = vert_in[f, k, q] - pc
        dd = wp.dot(d, d)
        if dd > 1.0e-12:
            if nxt < 0:
                nxt = q
                e = d
                ee = dd
            else:
                cr = _cross(e, d)
                # q replaces nxt if it lies right of cur -> nxt (cr < -tol), or on that line
                # (|cr| <= tol) and beyond nxt; tol = 1e-6 |d| |e|, taken only where the sign
                # of cr does not decide
                take = False
                if dd > ee:
                    take = cr <= 0.0 or cr <= 1.0e-6 * wp.sqrt(dd * ee)
                else:
                    take = cr < 0.0 and cr < -1.0e-6 * wp.sqrt(dd * ee)
                if take:
                    nxt = q
                    e = d
                    ee = dd
    return nxt


@wp.kernel
def _hulls(sides: wp.array(dtype=int), pad: float, o: Outlines):
    f, k = wp.tid()
    o.count[f, k] = 0
    o.bound[f, k] = _EMPTY_BOUND
    if o.visible[f, k] == 0:
        return
    n = 2 * sides[k]

    start = int(0)
    for q in range(1, n):
        p, s = o.vertices[f, k, q], o.vertices[f, k, start]
        if p[1] < s[1] or (p[1] == s[1] and p[0] < s[0]):
            start = q
    count = int(0)
    cur = start
    while count < MAX_HULL:
        o.hull[f, k, count] = cur
        count += 1
        cur = _hull_step(o.vertices, f, k, n, cur)
        if cur < 0 or cur == start:
            break
    if count < 3:
        return

    lo = wp.vec2(1.0e30, 1.0e30)
    hi = wp.vec2(-1.0e30, -1.0e30)
    miter = float(1.0)
    for e in range(count):
        a = o.vertices[f, k, o.hull[f, k, e]]
        d = o.vertices[f, k, o.hull[f, k, (e + 1) % count]] - a
        normal = wp.vec2(d[1], -d[0]) / wp.max(wp.length(d), 1.0e-12)
        o.line[f, k, e] = wp.vec3(normal[0], normal[1], wp.dot(normal, a))
        lo = wp.min(lo, a)
        hi = wp.max(hi, a)
    for e in range(count):
        prev = o.line[f, k, (e + count - 1) % count]
        line = o.line[f, k, e]
        cosine = prev[0] * line[0] + prev[1] * line[1]
        miter = wp.max(miter, wp.min(wp.sqrt(2.0 / wp.max(1.0 + cosine, 1.0e-6)), MITER_CAP))
    reach = pad * miter
    o.bound[f, k] = wp.vec4(lo[0] - reach, lo[1] - reach, hi[0] + reach, hi[1] + reach)
    o.count[f, k] = count


@wp.func
def _inside(bound: wp.vec4, u: float, v: float) -> bool:
    return u >= bound[0] and u <= bound[2] and v >= bound[1] and v <= bound[3]


@wp.func
def _edge_range(line: wp.vec3, lo: wp.vec2, hi: wp.vec2) -> wp.vec2:
    """Min and max of the edge line's distance over the rectangle [lo, hi] (at its corners)."""
    base = line[0] * lo[0] + line[1] * lo[1] - line[2]
    du = line[0] * (hi[0] - lo[0])
    dv = line[1] * (hi[1] - lo[1])
    return wp.vec2(base + wp.min(du, 0.0) + wp.min(dv, 0.0), base + wp.max(du, 0.0) + wp.max(dv, 0.0))


@wp.func
def _distance_bounds(o: Outlines, f: int, k: int, edges: wp.uint32, lo: wp.vec2, hi: wp.vec2) -> tuple[float, float]:
    """Bounds of primitive k's signed distance over the rectangle [lo, hi] from its hull edges in
    ``edges`` (bit e: edge e): the largest per-edge minimum (a lower bound) and the largest
    per-edge maximum (an upper bound)."""
    floor = float(-1.0e30)
    top = float(-1.0e30)
    rest = edges
    while rest != wp.uint32(0):
        e = _lowest(rest)
        rest = rest & (rest - wp.uint32(1))
        r = _edge_range(o.line[f, k, e], lo, hi)
        floor = wp.max(floor, r[0])
        top = wp.max(top, r[1])
    return floor, top


@wp.func
def _tile_classes(
    o: Outlines,
    f: int,
    lo: wp.vec2,
    hi: wp.vec2,
    limit: float,
) -> tuple[int, int, _EDGE_SETS]:
    """Classify the primitives against the tile whose pixel centres span [lo, hi].

    Returns bit masks (partial, full) of the primitives whose soft band meets the tile and of
    those with coverage exactly 1 all over it, and per partial primitive the set of hull
    edges that can hold the signed distance somewhere in the tile where it is >= -limit: an
    edge whose max over the tile is below the largest per-edge min over the tile (a lower
    bound of sd there), or below -limit, never does.
    """
    partial = int(0)
    full = int(0)
    edges = _EDGE_SETS()
    for k in range(o.count.shape[1]):
        b = o.bound[f, k]
        count = o.count[f, k]
        if count > 0 and b[2] >= lo[0] and b[0] <= hi[0] and b[3] >= lo[1] and b[1] <= hi[1]:
            floor, top = _distance_bounds(o, f, k, _ALL_BITS >> wp.uint32(32 - count), lo, hi)
            if top < -limit:
                full = full | (1 << k)
            elif floor <= limit:
                keep = wp.max(floor, -limit)
                for e in range(count):
                    if _edge_range(o.line[f, k, e], lo, hi)[1] >= keep:
                        edges[k] = edges[k] | (wp.uint32(1) << wp.uint32(e))
                partial = partial | (1 << k)
    return partial, full, edges


@wp.func
def _row_classes(
    o: Outlines, f: int, partial: int, edges: _EDGE_SETS, lo: wp.vec2, hi: wp.vec2, limit: float
) -> tuple[int, int]:
    """The tile's ``partial`` primitives split over a row of it whose pixel centres span [lo, hi]:
    bit masks (partial, full) of those whose soft band meets the row and of those with coverage
    exactly 1 all along it; the others are out of reach there. The tile's edge sets suffice: an
    edge left out of one is below the signed distance or below -limit all over the tile."""
    row_partial = int(0)
    row_full = int(0)
    rest = partial
    while rest != 0:
        k = _lowest(rest)
        rest = rest & (rest - 1)
        floor, top = _distance_bounds(o, f, k, edges[k], lo, hi)
        if top < -limit:
            row_full = row_full | (1 << k)
        elif floor <= limit:
            row_partial = row_partial | (1 << k)
    return row_partial, row_full


@wp.func
def _signed_distance(
    o: Outlines, f: int, k: int, edges: wp.uint32, p: wp.vec2, limit: float
) -> tuple[float, int]:
    """Signed distance [px] of p to hull k over a set of its edges, and the edge holding it;
    stops early once above ``limit``."""
    sd = float(-1.0e30)
    edge = int(0)
    rest = edges
    while rest != wp.uint32(0):
        e = _lowest(rest)
        rest = rest & (rest - wp.uint32(1))
        line = o.line[f, k, e]
        d = line[0] * p[0] + line[1] * p[1] - line[2]
        if d > sd:
            sd = d
            edge = e
            if sd > limit:
                return sd, edge
    return sd, edge


@wp.func
def _ray(intrinsics: wp.vec4, p: wp.vec2) -> wp.vec3:
    """Camera-frame ray direction (unit depth) through pixel point p; intrinsics (fx, fy, cx, cy)."""
    return wp.vec3((p[0] - intrinsics[2]) / intrinsics[0], (p[1] - intrinsics[3]) / intrinsics[1], 1.0)


@wp.func
def _depth(intrinsics: wp.vec4, o: Outlines, f: int, k: int, sd: _LAYERS, edge: _EDGES, p: wp.vec2,
           behind: float) -> float:
    """Depth [m] at p of primitive k: the entry depth of the ray through p (the max over faces
    with n . r < 0 of d / n . r, camera-facing faces only); outside its hull (sd > 0, the soft
    band), that of the ray through the nearest hull point, so that depth stays continuous where
    coverage is nonzero: a ray that misses a prism has no meaningful entry depth. Stops at the
    first partial max above ``behind``."""
    q = p
    if sd[k] > 0.0:
        count = o.count[f, k]
        a = o.vertices[f, k, o.hull[f, k, edge[k]]]
        d = o.vertices[f, k, o.hull[f, k, (edge[k] + 1) % count]] - a
        q = a + wp.clamp(wp.dot(p - a, d) / wp.max(wp.dot(d, d), 1.0e-12), 0.0, 1.0) * d
    ray = _ray(intrinsics, q)
    depth = float(-1.0e30)
    for i in range(o.plane_count[f, k]):
        plane = o.plane[f, k, i]
        nr = plane[0] * ray[0] + plane[1] * ray[1] + plane[2] * ray[2]
        if nr < 0.0:
            depth = wp.max(depth, plane[3] / nr)
            if depth > behind:
                break
    return depth


@wp.func
def _depths(
    intrinsics: wp.vec4,
    o: Outlines,
    f: int,
    bits: int,
    sd: _LAYERS,
    edge: _EDGES,
    p: wp.vec2,
) -> _LAYERS:
    """Depths [m] at p of the primitives in ``bits`` (:func:`_depth`), as far as their order
    needs: primitive 0 (the hand, the prism of most faces) comes last, and where it is behind
    every other layer its depth is a partial max already beyond theirs (it is behind the object
    at most pixels where they meet)."""
    z = _LAYERS()
    behind = float(-1.0e30)
    rest = bits & ~1
    while rest != 0:
        k = _lowest(rest)
        rest = rest & (rest - 1)
        z[k] = _depth(intrinsics, o, f, k, sd, edge, p, 1.0e30)
        behind = wp.max(behind, z[k])
    if bits & 1:
        z[0] = _depth(intrinsics, o, f, 0, sd, edge, p, behind)
    return z


@wp.func
def _in_front(z: _LAYERS, a: int, b: int) -> bool:
    """Whether layer a is in front of layer b (ties broken by index)."""
    return z[a] < z[b] or (z[a] == z[b] and a < b)


@wp.func
def _transmittance(c: _LAYERS, z: _LAYERS, bits: int, k: int, skip: int) -> float:
    """prod (1 - c_l) over the layers l in ``bits`` in front of k, leaving out k and ``skip``."""
    t = float(1.0)
    rest = bits
    while rest != 0:
        l = _lowest(rest)
        rest = rest & (rest - 1)
        if l != k and l != skip and _in_front(z, l, k):
            t = t * (1.0 - c[l])
    return t


@wp.func
def _tile_corners(x0: int, y0: int, H: int, W: int) -> tuple[wp.vec2, wp.vec2]:
    """First and last pixel centres of the tile at (x0, y0)."""
    lo = wp.vec2(float(x0) + 0.5, float(y0) + 0.5)
    hi = wp.vec2(float(wp.min(x0 + TILE, W)) - 0.5, float(wp.min(y0 + TILE, H)) - 0.5)
    return lo, hi


@wp.func
def _keep_bands(kept: Layers, f: int, i: int, tx: int, partial: int, bands: _EDGES):
    """Keep the soft-band masks of row i of tile column tx for the tile's ``partial`` primitives."""
    rest = partial
    while rest != 0:
        k = _lowest(rest)
        rest = rest & (rest - 1)
        kept.band[f, k, i, tx] = bands[k]


@wp.func
def _mask_grad(mask_grad_in: wp.array4d(dtype=float), t: int, f: int, k: int, i: int, j: int) -> float:
    """dL/dv of the visible mask of primitive k at pixel (i, j) of frame f, given per pixel."""
    return mask_grad_in[f, k, i, j]


@wp.func
def _mask_grad(grads: Profiles, t: int, f: int, k: int, i: int, j: int) -> float:
    """dL/dv of the visible mask of primitive k at pixel (i, j) of frame f from the gradients of the profiles (row
    sum i, column sum j, overlap with target frame t)."""
    return grads.rows[f, k, i] + grads.cols[f, k, j] + grads.overlap[f, k] * grads.target[t, k, i, j]


@wp.func
def _edge_vertex_grads(g: float, m: wp.vec2, e: wp.vec2) -> tuple[wp.vec2, wp.vec2]:
    """dL/da, dL/db of hull edge a -> b from its moments G = sum g and M = sum g (p - a), e = b - a.

    sd(p) = cross(p - a, e) / |e| is linear in p, so sum_p g_p sd(p) = cross(M, e) / |e|; its
    derivatives with respect to a and b follow with G, M held fixed and M's own dependence
    on a (dM/da = -G)."""
    length = wp.max(wp.length(e), 1.0e-12)
    cross = m[0] * e[1] - m[1] * e[0]
    grad_b = wp.vec2(-m[1], m[0]) / length - cross * e / (length * length * length)
    normal = wp.vec2(e[1], -e[0]) / length
    return -grad_b - g * normal, grad_b


@functools.cache
def _kernels(profiled: bool):
    """The forward and backward raster kernels drawing the visible masks (F, P, H, W), or with ``profiled``
    only their :class:`Profiles` (and taking their gradients)."""
    Drawn = Profiles if profiled else wp.array4d(dtype=float)

    @wp.kernel(module="unique", module_options=_OPTIONS)
    def _forward(
        # Model:
        intrinsics: wp.vec4,
        sigma: float,
        lanes: int,
        # Data in:
        o: Outlines,
        # Data out:
        kept: Layers,
        out: Drawn,
    ):
        f, ty, tx, lane = wp.tid()
        H, W = kept.covered.shape[1], kept.covered.shape[2]
        x0, y0 = tx * TILE, ty * TILE
        x1 = wp.min(x0 + TILE, W)
        lo, hi = _tile_corners(x0, y0, H, W)
        limit = CUTOFF * sigma
        partial, full, edges = _tile_classes(o, f, lo, hi, limit)
        if lane == 0:
            kept.tiles[f, ty, tx] = partial
        if partial == 0 and full == 0:
            return
        t = int(0)
        if wp.static(profiled):
            t = out.frame[f]
        overlap = _LAYERS()
        coverage = _ROW_VALUES()  # per partial primitive along the row, where it covers a pixel
        distance = _ROW_VALUES()
        distance_edge = _ROW_EDGES()
        for i in range(y0 + lane, wp.min(y0 + TILE, H), lanes):
            v_row = float(i) + 0.5
            row = _LAYERS()
            bands = _EDGES()
            row_lo, row_hi = wp.vec2(lo[0], v_row), wp.vec2(hi[0], v_row)
            row_partial, row_full = _row_classes(o, f, partial, edges, row_lo, row_hi, limit)
            if row_partial == 0 and row_full == 0 and full == 0:
                _keep_bands(kept, f, i, tx, partial, bands)
                continue
            # The partial primitives one after another along the row: coverage, distance and edge
            # where it covers a pixel (in the soft band, coverage and edge kept for the backward pass).
            covering = _ROW_BITS()
            rest = row_partial
            while rest != 0:
                k = _lowest(rest)
                rest = rest & (rest - 1)
                bound = o.bound[f, k]
                for j in range(x0, x1):
                    u = float(j) + 0.5
                    if _inside(bound, u, v_row):
                        d, e = _signed_distance(o, f, k, edges[k], wp.vec2(u, v_row), limit)
                        if d <= limit:
                            b = j - x0
                            covering[b] = covering[b] | (1 << k)
                            ck = float(1.0)
                            if d >= -limit:
                                ck = 1.0 / (1.0 + wp.exp(d / sigma))
                                bands[k] = bands[k] | (1 << b)
                                kept.band_coverage[f, k, i, j] = ck
                                kept.edge[f, k, i, j] = e
                            coverage[k, b] = ck
                            distance[k, b] = d
                            distance_edge[k, b] = e
            # Then pixel by pixel: one layer shows as it covers; two or more are sorted by depth
            # (written out in the kernel: functions taking the row's buffers would copy them).
            whole = full | row_full
            for j in range(x0, x1):
                b = j - x0
                covered = whole | covering[b]
                if covered == 0:
                    continue
                kept.covered[f, i, j] = covered
                v = _LAYERS()
                if covered & (covered - 1) == 0:
                    k = _lowest(covered)
                    v[k] = 1.0
                    if covering[b] != 0:
                        v[k] = coverage[k, b]
                else:
                    c = _LAYERS()
                    sd = _LAYERS()
                    edge = _EDGES()
                    rest = covered
                    while rest != 0:
                        k = _lowest(rest)
                        rest = rest & (rest - 1)
                        if (whole >> k) & 1:
                            c[k] = 1.0
                            sd[k] = -1.0e30
                        else:
                            c[k] = coverage[k, b]
                            sd[k] = distance[k, b]
                            edge[k] = distance_edge[k, b]
                    z = _depths(intrinsics, o, f, covered, sd, edge, wp.vec2(float(j) + 0.5, v_row))
                    rest = covered
                    while rest != 0:
                        k = _lowest(rest)
                        rest = rest & (rest - 1)
                        v[k] = c[k] * _transmittance(c, z, covered, k, -1)
                        kept.coverage[f, k, i, j] = c[k]
                        kept.depth[f, k, i, j] = z[k]
                rest = covered
                while rest != 0:
                    k = _lowest(rest)
                    rest = rest & (rest - 1)
                    if wp.static(profiled):
                        row[k] += v[k]
                        wp.atomic_add(out.cols, f, k, j, v[k])
                        overlap[k] += v[k] * out.target[t, k, i, j]
                    else:
                        out[f, k, i, j] = v[k]
            _keep_bands(kept, f, i, tx, partial, bands)
            if wp.static(profiled):
                for k in range(o.count.shape[1]):
                    if row[k] != 0.0:
                        wp.atomic_add(out.rows, f, k, i, row[k])
        if wp.static(profiled):
            for k in range(o.count.shape[1]):
                if overlap[k] != 0.0:
                    wp.atomic_add(out.overlap, f, k, overlap[k])

    @wp.kernel(module="unique", module_options=_OPTIONS)
    def _backward(
        # Model:
        sigma: float,
        lanes: int,
        # Data in:
        o: Outlines,
        kept: Layers,
        grad_in: Drawn,
        # Data out:
        vertex_grad_out: wp.array3d(dtype=wp.vec2),
    ):
        f, k, tile, lane = wp.tid()
        ty, tx = tile // kept.tiles.shape[2], tile % kept.tiles.shape[2]
        if (kept.tiles[f, ty, tx] >> k) & 1 == 0:  # coverage is constant (0 or 1) over the tile
            return
        H = kept.covered.shape[1]
        x0, y0 = tx * TILE, ty * TILE
        bit = 1 << k
        t = int(0)
        if wp.static(profiled):
            t = grad_in.frame[f]
        count = o.count[f, k]
        origin = wp.vec2(float(x0 + TILE // 2), float(y0 + TILE // 2))  # moments about the tile centre
        acc = _MOMENTS()
        for i in range(y0 + lane, wp.min(y0 + TILE, H), lanes):
            band = kept.band[f, k, i, tx]  # where the forward pass drew k's soft band in this row
            while band != 0:
                j = x0 + _lowest(band)
                band = band & (band - 1)
                p = wp.vec2(float(j) + 0.5, float(i) + 0.5)
                ek = kept.edge[f, k, i, j]
                ck = kept.band_coverage[f, k, i, j]
                dc = _mask_grad(grad_in, t, f, k, i, j)
                covered = kept.covered[f, i, j]  # the layers at the pixel, k among them
                others = covered - (covered & bit)
                if others != 0:
                    c = _LAYERS()
                    z = _LAYERS()
                    rest = covered
                    while rest != 0:
                        m = _lowest(rest)
                        rest = rest & (rest - 1)
                        c[m] = kept.coverage[f, m, i, j]
                        z[m] = kept.depth[f, m, i, j]
                    dc = dc * _transmittance(c, z, covered, k, -1)
                    rest = others
                    while rest != 0:
                        m = _lowest(rest)
                        rest = rest & (rest - 1)
                        if _in_front(z, k, m):
                            g_m = _mask_grad(grad_in, t, f, m, i, j)
                            dc = dc - g_m * c[m] * _transmittance(c, z, covered, m, k)
                g = -dc * ck * (1.0 - ck) / sigma
                acc[ek, 0] += g
                acc[ek, 1] += g * (p[0] - origin[0])
                acc[ek, 2] += g * (p[1] - origin[1])
        for e in range(count):
            if acc[e, 0] != 0.0:
                ia = o.hull[f, k, e]
                ib = o.hull[f, k, (e + 1) % count]
                a = o.vertices[f, k, ia]
                shift = origin - a
                moment = wp.vec2(acc[e, 1] + acc[e, 0] * shift[0], acc[e, 2] + acc[e, 0] * shift[1])
                grad_a, grad_b = _edge_vertex_grads(acc[e, 0], moment, o.vertices[f, k, ib] - a)
                wp.atomic_add(vertex_grad_out, f, k, ia, grad_a)
                wp.atomic_add(vertex_grad_out, f, k, ib, grad_b)

    return _forward, _backward


def _tiles(height: int, width: int) -> tuple[int, int]:
    return (height + TILE - 1) // TILE, (width + TILE - 1) // TILE


def lanes(device: wp.Device) -> int:
    """Threads per tile of :func:`rasterize` and :func:`rasterize_backward` on ``device``: one on
    the CPU (Warp runs its threads one after another there), a thread per row on a GPU."""
    return 1 if device.is_cpu else TILE


def build_hulls(sides: wp.array, pad: float, outlines: Outlines) -> None:
    """The hulls of ``outlines`` (its ``hull``, ``count``, ``line`` and ``bound``, bounds padded by
    ``pad`` [px]) from its ``visible`` and ``vertices``; ``sides`` (P,) int32 each prism's sides."""
    wp.launch(_hulls, dim=outlines.count.shape, inputs=[sides, pad, outlines], device=outlines.count.device)


def rasterize(intrinsics: wp.vec4, sigma: float, outlines: Outlines, kept: Layers, out) -> None:
    """Draw ``outlines`` (hulls built) with edge softness ``sigma`` [px] through a camera of ``intrinsics`` (fx, fy,
    cx, cy) [px] into ``out``: the zero-initialised visible soft masks v (F, P, H, W), or, a :class:`Profiles`,
    only the profiles of v against its targets (its sums zero-initialised). What the backward pass reads goes to
    ``kept``. A tile takes :func:`lanes` threads."""
    covered = kept.covered
    threads = lanes(covered.device)
    dim = (covered.shape[0], *_tiles(covered.shape[1], covered.shape[2]), threads)
    forward, _ = _kernels(_profiled(out))
    wp.launch(forward, dim=dim, inputs=[intrinsics, sigma, threads, outlines], outputs=[kept, out],
              device=covered.device)


def rasterize_backward(sigma: float, outlines: Outlines, kept: Layers, grad_in, vertex_grad: wp.array) -> None:
    """dL/d(projected vertices) (F, P, V) into the zero-initialised ``vertex_grad``, from the outlines and the
    layers :func:`rasterize` kept. ``grad_in`` is dL/dv (F, P, H, W), or the gradients of the profiles (a
    :class:`Profiles`, as :func:`rasterize` drew). A tile takes :func:`lanes` threads per primitive."""
    coverage = kept.coverage
    threads = lanes(coverage.device)
    rows, cols = _tiles(coverage.shape[2], coverage.shape[3])
    dim = (coverage.shape[0], coverage.shape[1], rows * cols, threads)
    _, backward = _kernels(_profiled(grad_in))
    wp.launch(backward, dim=dim, inputs=[sigma, threads, outlines, kept, grad_in], outputs=[vertex_grad],
              device=vertex_grad.device)


def _profiled(drawn) -> bool:
    """Whether the kernels draw profiles (``drawn`` a :class:`Profiles`) rather than masks (an array)."""
    return not wp.types.is_array(drawn)
