"""The per-mask losses of the optimiser from the rendered masks' profiles (``warpskill.optimizer.losses``, whose
Torch functions are their reference): dIoU, the box dIoU of masks drawn from boxes, and the hidden-part loss.

A rendered mask's profile is its row sums r_i (H,), column sums c_j (W,) and overlap o with the target mask.
With pixel centres v_i = i + 1/2, u_j = j + 1/2, :func:`moments` reduces it to the mass m = sum r_i, the first
moments (sum c_j u_j, sum r_i v_i), the second moments about the centroid (sum c_j (u_j - u)^2, sum r_i (v_i - v)^2)
and the box of the rows and columns holding at least half a pixel (no gradient). :func:`losses` turns them into
the loss per mask; its adjoint (Warp's reverse mode) gives the gradients of the moments, which :func:`spread`
takes to the rows and columns: dL/dr_i = g_m + g_v v_i + g_vv (v_i - v)^2, dL/dc_j = g_u u_j + g_uu (u_j - u)^2
(the second moments' dependence on the centroid vanishes: sum r_i (v_i - v) = 0).
"""

import functools

import warp as wp

from . import OPTIMIZATION_LEVEL

EMPTY_MASS = 1.0e-3
"""[px]: a mask with less total mass than this counts as empty."""

_FORWARD_ONLY = {"optimization_level": OPTIMIZATION_LEVEL, "enable_backward": False}


@functools.cache
def records(dtype):
    """The kernels' records for scalar type ``dtype``: (``Targets``, ``Profiles``, ``Moments``) Warp struct types.

    ``Targets``: ``boxed`` (C,) int32 (1: the channel's targets are boxes: box dIoU), ``typical_mass`` (C,) [px],
    the targets' ``mass`` (N, C) [px], ``centroid`` (N, C) (u, v) [px], ``box`` (N, C) and ``absent`` (N, C) int32
    (1: the part is known to be out of sight: hidden-part loss; read only by the ``hidden`` loss kernel).
    ``Profiles``: the rendered masks' row sums ``rows`` (N, C, H), column sums ``cols`` (N, C, W) and overlaps
    ``overlap`` (N, C) [px] with the targets, or their gradients. ``Moments``: :func:`moments`'s mass (N, C) [px],
    first moments (N, C) (u, v) [px^2], second moments about the centroid (N, C) (u, v) [px^3] and box (N, C)
    (u0, v0, u1, v1) [px], or their gradients (no box).
    """
    vec2, vec4 = wp.types.vector(2, dtype), wp.types.vector(4, dtype)

    @wp.struct
    class Targets:
        boxed: wp.array(dtype=int)
        typical_mass: wp.array(dtype=dtype)
        mass: wp.array2d(dtype=dtype)
        centroid: wp.array2d(dtype=vec2)
        box: wp.array2d(dtype=vec4)
        absent: wp.array2d(dtype=int)

    @wp.struct
    class Profiles:
        rows: wp.array3d(dtype=dtype)
        cols: wp.array3d(dtype=dtype)
        overlap: wp.array2d(dtype=dtype)

    @wp.struct
    class Moments:
        mass: wp.array2d(dtype=dtype)
        first: wp.array2d(dtype=vec2)
        second: wp.array2d(dtype=vec2)
        box: wp.array2d(dtype=vec4)

    return Targets, Profiles, Moments


@functools.cache
def _kernels(dtype):
    """The moment and gradient-spreading kernels for scalar type ``dtype``."""
    vec2, vec4 = wp.types.vector(2, dtype), wp.types.vector(4, dtype)
    _, Profiles, Moments = records(dtype)

    @wp.func
    def first_and_box(profile: wp.array3d(dtype=dtype), n: int, c: int) -> vec4:
        """(mass, sum p_i x_i, first x_i - 1/2 and last x_i + 1/2 with p_i >= 1/2) of a profile p, x_i = i + 1/2."""
        mass = dtype(0.0)
        first = dtype(0.0)
        lo = dtype(wp.inf)
        hi = dtype(-wp.inf)
        half = dtype(0.5)
        for i in range(profile.shape[2]):
            p = profile[n, c, i]
            x = dtype(i) + half
            mass += p
            first += p * x
            if p >= half:
                lo = wp.min(lo, x - half)
                hi = wp.max(hi, x + half)
        return vec4(mass, first, lo, hi)

    @wp.func
    def second(profile: wp.array3d(dtype=dtype), n: int, c: int, centre: dtype) -> dtype:
        """sum p_i (x_i - centre)^2 of a profile p."""
        total = dtype(0.0)
        for i in range(profile.shape[2]):
            d = dtype(i) + dtype(0.5) - centre
            total += profile[n, c, i] * d * d
        return total

    @wp.kernel(module="unique", module_options=_FORWARD_ONLY)
    def _moments(
        # Data in:
        profile_in: Profiles,
        # Data out:
        moments_out: Moments,
    ):
        n, c = wp.tid()
        v = first_and_box(profile_in.rows, n, c)
        u = first_and_box(profile_in.cols, n, c)
        denominator = wp.max(v[0], dtype(EMPTY_MASS))
        moments_out.mass[n, c] = v[0]
        moments_out.first[n, c] = vec2(u[1], v[1])
        moments_out.second[n, c] = vec2(second(profile_in.cols, n, c, u[1] / denominator),
                                        second(profile_in.rows, n, c, v[1] / denominator))
        moments_out.box[n, c] = vec4(u[2], v[2], u[3], v[3])

    @wp.kernel(module="unique", module_options=_FORWARD_ONLY)
    def _spread(
        # Data in:
        moments_in: Moments,
        moments_grad_in: Moments,
        # Data out:
        profile_grad_out: Profiles,
    ):
        n, c = wp.tid()
        centroid = moments_in.first[n, c] / wp.max(moments_in.mass[n, c], dtype(EMPTY_MASS))
        g1 = moments_grad_in.first[n, c]
        g2 = moments_grad_in.second[n, c]
        for i in range(profile_grad_out.rows.shape[2]):
            x = dtype(i) + dtype(0.5)
            d = x - centroid[1]
            profile_grad_out.rows[n, c, i] = moments_grad_in.mass[n, c] + g1[1] * x + g2[1] * d * d
        for j in range(profile_grad_out.cols.shape[2]):
            x = dtype(j) + dtype(0.5)
            d = x - centroid[0]
            profile_grad_out.cols[n, c, j] = g1[0] * x + g2[0] * d * d

    return _moments, _spread


@functools.cache
def _loss_kernel(dtype, hidden: bool):
    """The loss kernel for scalar type ``dtype``, with the hidden-part loss where ``targets.absent`` if ``hidden``."""
    vec2, vec4 = wp.types.vector(2, dtype), wp.types.vector(4, dtype)
    Targets, Profiles, Moments = records(dtype)

    @wp.func
    def diou(mass: dtype, centroid: vec2, overlap: dtype, box: vec4, target_mass: dtype, target_centroid: vec2,
             target_box: vec4) -> dtype:
        """1 - IoU + |centroid offset|^2 / (diagonal of the union box)^2, the offset term at most 1."""
        one = dtype(1.0)
        iou = overlap / wp.max(mass + target_mass - overlap, dtype(EMPTY_MASS))
        du = wp.max(box[2], target_box[2]) - wp.min(box[0], target_box[0])
        dv = wp.max(box[3], target_box[3]) - wp.min(box[1], target_box[1])
        offset = centroid - target_centroid
        return one - iou + wp.min(wp.dot(offset, offset) / wp.max(du * du + dv * dv, one), one)

    @wp.func
    def box_diou(denominator: dtype, centroid: vec2, second: vec2, target_box: vec4) -> dtype:
        """dIoU of the box centroid +- sqrt(3) std (a uniform filling's box) against the target's box."""
        one = dtype(1.0)
        zero = dtype(0.0)
        reach = dtype(1.7320508075688772) * vec2(wp.sqrt(second[0] / denominator + one / dtype(12.0)),
                                                    wp.sqrt(second[1] / denominator + one / dtype(12.0)))
        lo = centroid - reach
        hi = centroid + reach
        t_lo = vec2(target_box[0], target_box[1])
        t_hi = vec2(target_box[2], target_box[3])
        overlap = (wp.max(wp.min(hi[0], t_hi[0]) - wp.max(lo[0], t_lo[0]), zero)
                   * wp.max(wp.min(hi[1], t_hi[1]) - wp.max(lo[1], t_lo[1]), zero))
        area = (hi[0] - lo[0]) * (hi[1] - lo[1])
        target_area = wp.max(t_hi[0] - t_lo[0], zero) * wp.max(t_hi[1] - t_lo[1], zero)
        iou = overlap / wp.max(area + target_area - overlap, dtype(EMPTY_MASS))
        centre = dtype(0.5) * (t_lo + t_hi)
        centre = vec2(wp.where(wp.isnan(centre[0]), zero, centre[0]),  # an empty target's inverted box
                      wp.where(wp.isnan(centre[1]), zero, centre[1]))
        span_u = wp.max(hi[0], t_hi[0]) - wp.min(lo[0], t_lo[0])
        span_v = wp.max(hi[1], t_hi[1]) - wp.min(lo[1], t_lo[1])
        offset = centroid - centre
        return one - iou + wp.min(wp.dot(offset, offset) / wp.max(span_u * span_u + span_v * span_v, one), one)

    @wp.kernel(module="unique", module_options={"optimization_level": OPTIMIZATION_LEVEL})
    def _losses(
        # Model and targets:
        targets: Targets,
        # Data in:
        profile_in: Profiles,
        moments_in: Moments,
        # Data out:
        loss_out: wp.array2d(dtype=dtype),
    ):
        n, c = wp.tid()
        mass = moments_in.mass[n, c]
        denominator = wp.max(mass, dtype(EMPTY_MASS))
        centroid = moments_in.first[n, c] / denominator
        loss = dtype(0.0)
        absent = int(0)
        if wp.static(hidden):
            absent = targets.absent[n, c]
        if absent != 0:
            loss = wp.min(mass / wp.max(targets.typical_mass[c], dtype(1.0)), dtype(1.0))
        elif targets.mass[n, c] > dtype(EMPTY_MASS):
            if mass <= dtype(EMPTY_MASS):
                loss = dtype(2.0)
            elif targets.boxed[c] != 0:
                loss = box_diou(denominator, centroid, moments_in.second[n, c], targets.box[n, c])
            else:
                loss = diou(mass, centroid, profile_in.overlap[n, c], moments_in.box[n, c], targets.mass[n, c],
                            targets.centroid[n, c], targets.box[n, c])
        loss_out[n, c] = loss

    return _losses


def moments(profile, moments_out) -> None:
    """The ``Moments`` (:func:`records`) of the masks whose ``Profiles`` are ``profile`` into ``moments_out``; the
    box inverted, (+inf, +inf, -inf, -inf), where no row or column holds half a pixel."""
    mass = moments_out.mass
    wp.launch(_kernels(mass.dtype)[0], dim=mass.shape, inputs=[profile], outputs=[moments_out], device=mass.device)


def losses(targets, hidden: bool, profile, moments_in, loss: wp.array, *, loss_grad: wp.array | None = None) -> None:
    """The loss (N, C) per mask into ``loss``, or with ``loss_grad`` its adjoint, adding dL/d(overlap) and
    dL/d(mass, first, second) into the gradients of those arrays of ``profile`` and ``moments_in``.

    ``targets``, ``profile``, ``moments_in``: the :func:`records` of the targets and of the rendered masks; with
    ``hidden`` the hidden-part loss where ``targets.absent``. Where the target is empty and the part not absent the
    loss is 0; where only the rendering is empty, 2.
    """
    kernel = _loss_kernel(loss.dtype, hidden)
    inputs = [targets, profile, moments_in]
    if loss_grad is None:
        wp.launch(kernel, dim=loss.shape, inputs=inputs, outputs=[loss], device=loss.device)
        return
    no_adjoint = [type(record)() for record in inputs]  # a struct's adjoint goes to its arrays' gradients
    wp.launch(kernel, dim=loss.shape, inputs=inputs, outputs=[loss], device=loss.device, adj_inputs=no_adjoint,
              adj_outputs=[loss_grad], adjoint=True)


def spread(moments_in, moments_grad, profile_grad) -> None:
    """dL/d(row sums) (N, C, H) and dL/d(column sums) (N, C, W) into ``profile_grad`` from the gradients
    ``moments_grad`` of the mass, first and second moments ``moments_in`` (:func:`losses`'s adjoint)."""
    mass = moments_in.mass
    wp.launch(_kernels(mass.dtype)[1], dim=mass.shape, inputs=[moments_in, moments_grad], outputs=[profile_grad],
              device=mass.device)
