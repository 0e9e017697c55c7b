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


@functools.cache
def _kernels(dtype):
    """The moment, loss and gradient-spreading kernels for scalar type ``dtype``."""
    vec2, vec4 = wp.types.vector(2, dtype), wp.types.vector(4, dtype)
    options = {"optimization_level": OPTIMIZATION_LEVEL, "enable_backward": False}

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

    @wp.kernel(module="unique", module_options=options)
    def _moments(
        # Data in:
        rows_in: wp.array3d(dtype=dtype),
        cols_in: wp.array3d(dtype=dtype),
        # Data out:
        mass_out: wp.array2d(dtype=dtype),
        first_out: wp.array2d(dtype=vec2),
        second_out: wp.array2d(dtype=vec2),
        box_out: wp.array2d(dtype=vec4),
    ):
        n, c = wp.tid()
        v = first_and_box(rows_in, n, c)
        u = first_and_box(cols_in, n, c)
        denominator = wp.max(v[0], dtype(EMPTY_MASS))
        mass_out[n, c] = v[0]
        first_out[n, c] = vec2(u[1], v[1])
        second_out[n, c] = vec2(second(cols_in, n, c, u[1] / denominator), second(rows_in, n, c, v[1] / denominator))
        box_out[n, c] = vec4(u[2], v[2], u[3], v[3])

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
        # Model:
        boxed: wp.array(dtype=int),
        typical_mass: wp.array(dtype=dtype),
        # Data in (targets):
        target_mass_in: wp.array2d(dtype=dtype),
        target_centroid_in: wp.array2d(dtype=vec2),
        target_box_in: wp.array2d(dtype=vec4),
        absent_in: wp.array2d(dtype=int),
        # Data in (rendered):
        overlap_in: wp.array2d(dtype=dtype),
        mass_in: wp.array2d(dtype=dtype),
        first_in: wp.array2d(dtype=vec2),
        second_in: wp.array2d(dtype=vec2),
        box_in: wp.array2d(dtype=vec4),
        # Data out:
        loss_out: wp.array2d(dtype=dtype),
    ):
        n, c = wp.tid()
        mass = mass_in[n, c]
        denominator = wp.max(mass, dtype(EMPTY_MASS))
        centroid = first_in[n, c] / denominator
        loss = dtype(0.0)
        absent = int(0)
        if absent_in.shape[0] > 0:
            absent = absent_in[n, c]
        if absent != 0:
            loss = wp.min(mass / wp.max(typical_mass[c], dtype(1.0)), dtype(1.0))
        elif target_mass_in[n, c] > dtype(EMPTY_MASS):
            if mass <= dtype(EMPTY_MASS):
                loss = dtype(2.0)
            elif boxed[c] != 0:
                loss = box_diou(denominator, centroid, second_in[n, c], target_box_in[n, c])
            else:
                loss = diou(mass, centroid, overlap_in[n, c], box_in[n, c], target_mass_in[n, c],
                            target_centroid_in[n, c], target_box_in[n, c])
        loss_out[n, c] = loss

    @wp.kernel(module="unique", module_options=options)
    def _spread(
        # Data in:
        mass_in: wp.array2d(dtype=dtype),
        first_in: wp.array2d(dtype=vec2),
        mass_grad_in: wp.array2d(dtype=dtype),
        first_grad_in: wp.array2d(dtype=vec2),
        second_grad_in: wp.array2d(dtype=vec2),
        # Data out:
        rows_grad_out: wp.array3d(dtype=dtype),
        cols_grad_out: wp.array3d(dtype=dtype),
    ):
        n, c = wp.tid()
        centroid = first_in[n, c] / wp.max(mass_in[n, c], dtype(EMPTY_MASS))
        g1 = first_grad_in[n, c]
        g2 = second_grad_in[n, c]
        for i in range(rows_grad_out.shape[2]):
            x = dtype(i) + dtype(0.5)
            d = x - centroid[1]
            rows_grad_out[n, c, i] = mass_grad_in[n, c] + g1[1] * x + g2[1] * d * d
        for j in range(cols_grad_out.shape[2]):
            x = dtype(j) + dtype(0.5)
            d = x - centroid[0]
            cols_grad_out[n, c, j] = g1[0] * x + g2[0] * d * d

    return _moments, _losses, _spread


def moments(rows: wp.array, cols: wp.array, mass: wp.array, first: wp.array, second: wp.array, box: wp.array) -> None:
    """Mass (N, C) [px], first moments (N, C) (u, v) [px^2], second moments about the centroid (N, C) (u, v)
    [px^3] and box (N, C) (u0, v0, u1, v1) [px] (inverted, (+inf, +inf, -inf, -inf), where no row or column holds
    half a pixel) of masks of row sums ``rows`` (N, C, H) and column sums ``cols`` (N, C, W)."""
    kernel = _kernels(rows.dtype)[0]
    wp.launch(kernel, dim=mass.shape, inputs=[rows, cols], outputs=[mass, first, second, box], device=mass.device)


def losses(model: list, targets: list, rendered: list, loss: wp.array, rendered_grads: list | None = None,
           loss_grad: wp.array | None = None) -> None:
    """The loss (N, C) per mask into ``loss``, or with ``loss_grad`` its adjoint, adding dL/d``rendered`` into
    ``rendered_grads``.

    ``rendered_grads`` are those of all ``rendered`` but the box.

    ``model``: boxed (C,) int (1: the channel's targets are boxes: box dIoU) and the channels' typical masses
    (C,) [px]. ``targets``: their mass (N, C), centroid (N, C) (u, v) [px], box (N, C) and absent (N, C) int (1:
    the part is known to be out of sight: hidden-part loss), or (0, 0) for none. ``rendered``: the overlaps (N, C)
    [px] with the targets, then :func:`moments`'s outputs. Where the target is empty and the part not absent the
    loss is 0; where only the rendering is empty, 2.
    """
    kernel = _kernels(loss.dtype)[1]
    adjoint = loss_grad is not None
    wp.launch(kernel, dim=loss.shape, inputs=[*model, *targets, *rendered], outputs=[loss], device=loss.device,
              adj_inputs=[None] * (len(model) + len(targets)) + [*rendered_grads, None] if adjoint else [],
              adj_outputs=[loss_grad] if adjoint else [], adjoint=adjoint)


def spread(mass: wp.array, first: wp.array, grads: list, rows_grad: wp.array, cols_grad: wp.array) -> None:
    """dL/d(row sums) (N, C, H) and dL/d(column sums) (N, C, W) into ``rows_grad``, ``cols_grad`` from the
    gradients ``grads`` of the mass, first and second moments (:func:`losses`'s adjoint)."""
    kernel = _kernels(mass.dtype)[2]
    wp.launch(kernel, dim=mass.shape, inputs=[mass, first, *grads], outputs=[rows_grad, cols_grad],
              device=mass.device)
