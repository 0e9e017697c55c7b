"""Differentiable soft silhouettes of the hand and the cuboids (``docs/architecture.md``).

Two ``torch.autograd.Function``s over Warp kernels: the prisms' vertices and their projection
(``warpskill.kernels.prisms``), whose backward is Warp's adjoint, carrying gradients to poses, sizes and
the camera; and the raster (``warpskill.kernels.raster``), whose backward turns per-edge moments into
gradients with respect to the projected vertices in closed form.
"""

from __future__ import annotations

from typing import NamedTuple

import torch
import warp as wp

from warpskill.contract.camera import Intrinsics
from warpskill.engine.primitives import HAND_LENGTH, HAND_PRISM_RADIUS, HAND_SEGMENTS, NEAR_PLANE
from warpskill.engine.warp_bridge import WorkspacePool, as_warp, copy_into, make_struct, warp_scope
from warpskill.kernels import prisms, raster

_MAX_VERTICES = 2 * raster.MAX_SIDES
_MAX_PLANES = raster.MAX_SIDES + 2


def render_silhouettes(
    hand_pos: torch.Tensor,
    hand_rot: torch.Tensor,
    cuboid_pos: torch.Tensor,
    cuboid_rot: torch.Tensor,
    cuboid_size: torch.Tensor,
    camera_height: torch.Tensor,
    camera_elevation: torch.Tensor,
    intrinsics: Intrinsics,
    *,
    sigma: float = 1.0,
) -> torch.Tensor:
    """Soft visible masks of the hand and the cuboids in every frame.

    The hand is clipped to the part of its axis in front of the near plane
    (:func:`warpskill.engine.primitives.hand_axis_extent`); a cuboid with a vertex closer than
    ``NEAR_PLANE`` to the camera plane is not drawn.

    Args:
        hand_pos: (F, 3) hand tip positions [m].
        hand_rot: (F, 3, 3) hand rotations.
        cuboid_pos: (F, C, 3) cuboid centres [m], C >= 0.
        cuboid_rot: (F, C, 3, 3) cuboid rotations.
        cuboid_size: (C, 3) or (F, C, 3) cuboid edge lengths [m].
        camera_height: scalar camera height [m].
        camera_elevation: scalar camera elevation [rad].
        intrinsics: camera intrinsics; ``intrinsics.image_size`` (H, W) is the output size.
        sigma: edge softness [px]; coverage is sigmoid(-signed distance / sigma).

    Returns:
        (F, 1 + C, H, W) visible masks in [0, 1], in the dtype of ``hand_pos``: channel 0
        the hand, then the cuboids in order.
    """
    check_silhouette_inputs(
        hand_pos, hand_rot, cuboid_pos, cuboid_rot, cuboid_size, camera_height, camera_elevation, intrinsics, sigma
    )
    raster_inputs = _raster_inputs(hand_pos, hand_rot, cuboid_pos, cuboid_rot, cuboid_size, camera_height,
                                   camera_elevation, intrinsics)
    masks, _, _, _ = _SoftSilhouettes.apply(*raster_inputs, float(sigma), None, None)
    return masks.to(hand_pos.dtype)


def silhouette_profiles(
    hand_pos: torch.Tensor,
    hand_rot: torch.Tensor,
    cuboid_pos: torch.Tensor,
    cuboid_rot: torch.Tensor,
    cuboid_size: torch.Tensor,
    camera_height: torch.Tensor,
    camera_elevation: torch.Tensor,
    intrinsics: Intrinsics,
    targets: torch.Tensor,
    target_frame: torch.Tensor | None = None,
    *,
    sigma: float = 1.0,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """What the mask losses read of :func:`render_silhouettes`'s masks v, without forming them.

    The raster sums each mask's rows and columns and its overlap with a target mask t as it
    goes, and its backward pass takes their gradients: the image-sized masks, their
    gradient and the Torch reductions over them are never made.

    Args:
        hand_pos, hand_rot, cuboid_pos, cuboid_rot, cuboid_size, camera_height,
            camera_elevation, intrinsics, sigma: as :func:`render_silhouettes`.
        targets: (T, 1 + C, H, W) target masks.
        target_frame: (F,) integer index of each frame's targets (default: frame f reads
            ``targets[f]``, T = F).

    Returns:
        ``(rows, cols, overlap)``: (F, 1 + C, H) row sums sum_j v_ij, (F, 1 + C, W) column
        sums sum_i v_ij and (F, 1 + C) overlaps sum_ij v_ij t_ij [px], in the dtype of ``hand_pos``.
    """
    check_silhouette_inputs(
        hand_pos, hand_rot, cuboid_pos, cuboid_rot, cuboid_size, camera_height, camera_elevation, intrinsics, sigma
    )
    F, P = hand_pos.shape[0], 1 + cuboid_pos.shape[1]
    if target_frame is None:
        target_frame = torch.arange(F, device=hand_pos.device)
    if targets.dim() != 4 or tuple(targets.shape[1:]) != (P, *intrinsics.image_size):
        raise ValueError(f"targets must be (T, {P}, {intrinsics.image_size[0]}, {intrinsics.image_size[1]}), "
                         f"got {tuple(targets.shape)}")
    if target_frame.shape != (F,) or (F and not 0 <= int(target_frame.min()) <= int(target_frame.max()) < len(targets)):
        raise ValueError(f"target_frame must be ({F},) indices into the {len(targets)} target frames")
    raster_inputs = _raster_inputs(hand_pos, hand_rot, cuboid_pos, cuboid_rot, cuboid_size, camera_height,
                                   camera_elevation, intrinsics)
    _, rows, cols, overlap = _SoftSilhouettes.apply(*raster_inputs, float(sigma), targets, target_frame)
    return rows.to(hand_pos.dtype), cols.to(hand_pos.dtype), overlap.to(hand_pos.dtype)


def _raster_inputs(
    hand_pos, hand_rot, cuboid_pos, cuboid_rot, cuboid_size, camera_height, camera_elevation, intrinsics
) -> tuple:
    """The raster's inputs for a scene: projected vertices (F, P, V, 2) [px], face planes,
    visibility (F, P), prism sides (P,), intrinsics (fx, fy, cx, cy) and image size (H, W)."""
    dtype = hand_pos.dtype
    F, C = cuboid_pos.shape[:2]
    K = intrinsics.K
    camera_vec = (float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]))
    scene = (hand_pos, hand_rot, cuboid_pos.to(dtype), cuboid_rot.to(dtype), cuboid_size.to(dtype).expand(F, C, 3),
             camera_height.to(dtype).reshape(1), camera_elevation.to(dtype).reshape(1))
    pixels, planes, visible = _ProjectedPrisms.apply(camera_vec, *scene)
    sides = torch.tensor([HAND_SEGMENTS] + [4] * C, dtype=torch.int32, device=hand_pos.device)
    return pixels, planes, visible, sides, camera_vec, tuple(intrinsics.image_size)


class _ProjectedPrisms(torch.autograd.Function):
    """The prisms of a scene as the raster reads them (:mod:`warpskill.kernels.prisms`): projected vertices
    (F, P, V, 2) [px], differentiable, and, not differentiable, the face planes (F, P, 26, 4) in camera
    coordinates, camera-facing first (the others zeroed), and visibility (F, P) bool.

    Inputs: intrinsics (fx, fy, cx, cy) [px], then hand_pos (F, 3), hand_rot (F, 3, 3), cuboid_pos (F, C, 3),
    cuboid_rot (F, C, 3, 3), cuboid_size (F, C, 3), camera_height (1,) and camera_elevation (1,), of one dtype.
    The buffers come from a :class:`_PrismWorkspace` of the shape, held from forward to backward.
    """

    @staticmethod
    def forward(ctx, camera_vec, *scene):
        wp.init()  # no-op once Warp is up
        F, C = scene[2].shape[:2]
        device = scene[0].device
        work = _PRISM_POOL.take((F, C, scene[0].dtype, device))
        copy_into(work.scene, scene)
        with warp_scope(device):
            prisms.project(work.prisms, work.vec4(*camera_vec), work.scene_struct, work.views["pixel"])
            prisms.face_planes(work.prisms, work.scene_struct, *work.views["planes"])
        planes, visible = work.plane.clone(), work.visible != 0
        ctx.mark_non_differentiable(planes, visible)
        if any(ctx.needs_input_grad[1:]):
            ctx.work, ctx.camera_vec = work, camera_vec
        else:
            _PRISM_POOL.give_back(work.key, work)
        return work.pixel.clone(), planes, visible

    @staticmethod
    def backward(ctx, pixel_grad, _planes_grad, _visible_grad):
        work = ctx.work
        work.pixel_grad.copy_(pixel_grad)
        torch._foreach_zero_(work.scene_grad)
        with warp_scope(work.pixel.device):
            prisms.project(work.prisms, work.vec4(*ctx.camera_vec), work.scene_struct, work.views["pixel"],
                           work.views["pixel_grad"])
        grads = [grad.clone() if needed else None for grad, needed in zip(work.scene_grad, ctx.needs_input_grad[1:])]
        _PRISM_POOL.give_back(work.key, work)  # ctx keeps it: a second backward pass (retain_graph) reads it again
        return None, *grads


class _PrismWorkspace:
    """The buffers of :class:`_ProjectedPrisms` for F frames and C cuboids of one dtype, allocated once, with
    the kernels' records and views over them (made once): the scene's tensors (``scene``, in the Function's input
    order) and their gradients (``scene_grad``) in the record ``scene_struct``, the ``prisms`` record (their sides
    (P,), the hand prism's size, the near plane), the projected vertices ``pixel`` (F, P, V, 2) and their gradient,
    the face planes ``plane`` (F, P, 26, 4) with their count (F, P) int32 and ``visible`` (F, P) int32."""

    def __init__(self, key: tuple):
        F, C, dtype, device = key
        like = {"dtype": dtype, "device": device}
        self.key = key
        shapes = ((F, 3), (F, 3, 3), (F, C, 3), (F, C, 3, 3), (F, C, 3), (1,), (1,))
        self.scene = [torch.zeros(shape, **like) for shape in shapes]
        self.scene_grad = [torch.zeros(shape, **like) for shape in shapes]
        self.pixel = torch.zeros(F, 1 + C, _MAX_VERTICES, 2, **like)
        self.pixel_grad = torch.zeros_like(self.pixel)
        self.plane = torch.zeros(F, 1 + C, _MAX_PLANES, 4, **like)
        self.plane_count = torch.zeros(F, 1 + C, dtype=torch.int32, device=device)
        self.visible = torch.zeros(F, 1 + C, dtype=torch.int32, device=device)
        sides = torch.tensor([HAND_SEGMENTS] + [4] * C, dtype=torch.int32, device=device)
        scalar = wp.dtype_from_torch(dtype)
        vec2, vec3, vec4 = (wp.types.vector(n, scalar) for n in (2, 3, 4))
        self.vec4 = vec4
        mat33 = wp.types.matrix((3, 3), scalar)
        Prisms, Scene = prisms.records(scalar)
        with warp_scope(device):
            self.prisms = make_struct(Prisms, sides=as_warp(sides), radius=HAND_PRISM_RADIUS, length=HAND_LENGTH,
                                      near=NEAR_PLANE)
            self.scene_struct = make_struct(Scene, **{
                name: as_warp(x, t, grad=g) for name, x, g, t in
                zip(Scene.vars, self.scene, self.scene_grad, (vec3, mat33, vec3, mat33, vec3, None, None))})
            self.views = {
                "pixel": as_warp(self.pixel, vec2),
                "pixel_grad": as_warp(self.pixel_grad, vec2),
                "planes": [as_warp(self.plane, vec4), as_warp(self.plane_count), as_warp(self.visible)],
            }


_PRISM_POOL = WorkspacePool(_PrismWorkspace)


class _SoftSilhouettes(torch.autograd.Function):
    """Visible soft masks (F, P, H, W) from projected prism vertices (F, P, V, 2) [px], or
    only their profiles (row sums, column sums, overlaps) against target masks.

    Non-differentiable inputs: face planes (F, P, HAND_SEGMENTS + 2, 4) in camera coordinates, camera-facing
    first (:class:`_ProjectedPrisms`), visibility (F, P) bool, prism sides (P,) int32,
    intrinsics (fx, fy, cx, cy), image size (H, W), sigma [px], and the targets (T, P, H, W)
    with each frame's index into them (F,), or None for the masks.

    Outputs ``(masks, rows, cols, overlap)``: the masks (empty with targets), or the
    profiles (F, P, H), (F, P, W), (F, P) (empty without). The buffers between the two
    passes come from a :class:`_Workspace` of the shape, held from forward to backward.
    """

    @staticmethod
    def forward(ctx, pixels, planes, visible, sides, camera_vec, image_size, sigma, targets, target_frame):
        wp.init()  # no-op once Warp is up
        ctx.set_materialize_grads(False)  # a profile the loss does not read seeds nothing
        device = pixels.device
        profiled = targets is not None
        work = _POOL.take((tuple(pixels.shape), tuple(planes.shape), tuple(image_size), device, profiled))
        work.load(pixels, planes, visible)
        masks = torch.zeros(work.mask_shape, dtype=torch.float32, device=device)  # the call's own: image-sized
        torch._foreach_zero_(list(work.profiles))
        with warp_scope(device):
            if profiled:
                work.load_targets(targets, target_frame)
            raster.build_hulls(as_warp(sides), raster.CUTOFF * sigma, work.outlines)
            raster.rasterize(wp.vec4(*camera_vec), sigma, work.outlines, work.kept,
                             work.views["profiles"] if profiled else as_warp(masks))
        if ctx.needs_input_grad[0]:
            ctx.work, ctx.sigma = work, sigma
            ctx.save_for_backward(pixels.detach())
        else:
            _POOL.give_back(work.key, work)
        return masks, *(profile.clone() for profile in work.profiles)

    @staticmethod
    def backward(ctx, mask_grad, rows_grad, cols_grad, overlap_grad):
        (pixels,) = ctx.saved_tensors
        work = ctx.work
        for buffer, grad in zip(work.profile_grads, (rows_grad, cols_grad, overlap_grad)):
            if grad is None:  # a profile the loss does not read
                buffer.zero_()
            else:
                buffer.copy_(grad)
        work.vertex_grad.zero_()
        with warp_scope(pixels.device):
            if work.profiled:
                grad_in = work.views["profile_grads"]
            else:
                grad_in = as_warp(torch.zeros(work.mask_shape, device=pixels.device) if mask_grad is None
                                  else mask_grad.float())
            raster.rasterize_backward(ctx.sigma, work.outlines, work.kept, grad_in, work.views["vertex_grad"])
        vertex_grad = work.vertex_grad.to(pixels.dtype, copy=True)
        _POOL.give_back(work.key, work)
        del ctx.work
        return vertex_grad, None, None, None, None, None, None, None, None


class _Workspace:
    """The raster's buffers for one shape, allocated once and reused by every call of that shape,
    with the kernels' structs and views over them (made once): ``outlines`` (:class:`raster.Outlines`:
    the visibility, projected vertices, hulls and face planes), ``kept`` (:class:`raster.Layers`:
    what the forward pass keeps for the backward one), the ``profiles`` (M rows; M = F with
    targets, else 0) and their gradients ``profile_grads`` (:class:`raster.Profiles`, reading the
    targets at the frame indices ``frame`` (F,) int32), and the backward pass's output
    ``vertex_grad`` (F, P, V, 2). The image-sized masks and their gradient are the call's own.

    A call takes one from :data:`_POOL` and gives it back once its backward pass has run (at
    once without one).
    """

    def __init__(self, key: tuple):
        (F, P, V, _), plane_shape, (H, W), device, profiled = key
        i32, f32 = {"dtype": torch.int32, "device": device}, {"dtype": torch.float32, "device": device}
        made = F if profiled else 0
        self.key, self.profiled = key, profiled
        self.visible = torch.zeros(F, P, **i32)
        self.vertices = torch.zeros(F, P, V, 2, **f32)
        self.plane_count = torch.zeros(F, P, **i32)
        self.plane = torch.zeros(plane_shape, **f32)
        self.mask_shape = (F - made, P, H, W)  # the masks' (and their gradient's): F without targets, else none
        self.profiles, self.profile_grads = (
            _Profiles(*(torch.zeros(made, P, *size, **f32) for size in ((H,), (W,), ()))) for _ in range(2))
        self.frame = torch.zeros(F, **i32)
        self.vertex_grad = torch.zeros(F, P, V, 2, **f32)
        self._target: torch.Tensor | None = None  # the target masks the profiles' records read
        with warp_scope(device):
            self.outlines = make_struct(
                raster.Outlines, visible=as_warp(self.visible), vertices=as_warp(self.vertices, wp.vec2),
                hull=as_warp(torch.zeros(F, P, raster.MAX_HULL, **i32)), count=as_warp(torch.zeros(F, P, **i32)),
                line=as_warp(torch.zeros(F, P, raster.MAX_HULL, 3, **f32), wp.vec3),
                bound=as_warp(torch.zeros(F, P, 4, **f32), wp.vec4), plane_count=as_warp(self.plane_count),
                plane=as_warp(self.plane, wp.vec4))
            rows, cols = (H + raster.TILE - 1) // raster.TILE, (W + raster.TILE - 1) // raster.TILE
            self.kept = make_struct(
                raster.Layers, covered=as_warp(torch.zeros(F, H, W, **i32)),
                coverage=as_warp(torch.zeros(F, P, H, W, **f32)),
                depth=as_warp(torch.zeros(F, P, H, W, **f32)), tiles=as_warp(torch.zeros(F, rows, cols, **i32)),
                band=as_warp(torch.zeros(F, P, H, cols, **i32)),
                band_coverage=as_warp(torch.zeros(F, P, H, W, **f32)), edge=as_warp(torch.zeros(F, P, H, W, **i32)))
            frame = as_warp(self.frame)
            self.views = {"profiles": self.profiles.struct(frame), "profile_grads": self.profile_grads.struct(frame),
                          "vertex_grad": as_warp(self.vertex_grad, wp.vec2)}

    def load(self, pixels: torch.Tensor, planes: torch.Tensor, visible: torch.Tensor) -> None:
        """Copy a call's inputs in."""
        self.vertices.copy_(pixels.detach())
        self.plane.copy_(planes)
        self.plane_count.copy_((planes[..., 3] < 0).sum(dim=-1))
        self.visible.copy_(visible)

    def load_targets(self, masks: torch.Tensor, frame: torch.Tensor) -> None:
        """Read the profiles against target ``masks`` (T, P, H, W) at ``frame`` (F,): the frame indices copied in,
        the masks' view set in the profiles' records again only for other masks."""
        self.frame.copy_(frame)
        masks = masks.to(torch.float32).contiguous()
        if self._target is None or not _same_memory(self._target, masks):
            self._target = masks
            view = as_warp(masks)
            self.views["profiles"].target = self.views["profile_grads"].target = view


def _same_memory(a: torch.Tensor, b: torch.Tensor) -> bool:
    """Whether tensors ``a`` and ``b`` are views of the same memory (pointer, shape, strides, dtype)."""
    return (a.data_ptr(), a.shape, a.stride(), a.dtype) == (b.data_ptr(), b.shape, b.stride(), b.dtype)


_POOL = WorkspacePool(_Workspace)


class _Profiles(NamedTuple):
    """Row sums (F, P, H), column sums (F, P, W) and overlaps (F, P) of the masks, or their gradients."""

    rows: torch.Tensor
    cols: torch.Tensor
    overlap: torch.Tensor

    def struct(self, frame: wp.array) -> raster.Profiles:
        """The kernels' :class:`raster.Profiles` over zero-copy Warp views, reading targets at ``frame`` (the target
        masks set by :meth:`_Workspace.load_targets`)."""
        return make_struct(raster.Profiles, frame=frame, rows=as_warp(self.rows), cols=as_warp(self.cols),
                           overlap=as_warp(self.overlap))


def check_silhouette_inputs(
    hand_pos, hand_rot, cuboid_pos, cuboid_rot, cuboid_size, camera_height, camera_elevation, intrinsics, sigma
) -> None:
    """Raise ValueError on inputs :func:`render_silhouettes` cannot take."""
    tensors = {
        "hand_pos": hand_pos,
        "hand_rot": hand_rot,
        "cuboid_pos": cuboid_pos,
        "cuboid_rot": cuboid_rot,
        "cuboid_size": cuboid_size,
        "camera_height": camera_height,
        "camera_elevation": camera_elevation,
    }
    for name, t in tensors.items():
        if not isinstance(t, torch.Tensor) or not t.is_floating_point():
            raise ValueError(f"{name} must be a floating-point torch.Tensor, got {type(t).__name__}")
        if t.device != hand_pos.device:
            raise ValueError(f"{name} is on {t.device}, hand_pos on {hand_pos.device}")
    for name in ("camera_height", "camera_elevation"):
        if tensors[name].numel() != 1 or tensors[name].dim() > 1:
            raise ValueError(f"{name} must be a scalar tensor, got shape {tuple(tensors[name].shape)}")
    if hand_pos.dim() != 2 or hand_pos.shape[1] != 3:
        raise ValueError(f"hand_pos must be (F, 3), got {tuple(hand_pos.shape)}")
    F = hand_pos.shape[0]
    if hand_rot.shape != (F, 3, 3):
        raise ValueError(f"hand_rot must be ({F}, 3, 3), got {tuple(hand_rot.shape)}")
    if cuboid_pos.dim() != 3 or cuboid_pos.shape[0] != F or cuboid_pos.shape[2] != 3:
        raise ValueError(f"cuboid_pos must be ({F}, C, 3), got {tuple(cuboid_pos.shape)}")
    C = cuboid_pos.shape[1]
    if cuboid_rot.shape != (F, C, 3, 3):
        raise ValueError(f"cuboid_rot must be ({F}, {C}, 3, 3), got {tuple(cuboid_rot.shape)}")
    if cuboid_size.shape not in ((C, 3), (F, C, 3)):
        raise ValueError(f"cuboid_size must be ({C}, 3) or ({F}, {C}, 3), got {tuple(cuboid_size.shape)}")
    if 1 + C > raster.MAX_PRIMITIVES:
        raise ValueError(f"at most {raster.MAX_PRIMITIVES - 1} cuboids, got {C}")
    if not isinstance(intrinsics, Intrinsics):
        raise ValueError(f"intrinsics must be an Intrinsics, got {type(intrinsics).__name__}")
    if not (isinstance(sigma, (int, float)) and 0.0 < sigma < float("inf")):
        raise ValueError(f"sigma must be a positive finite number [px], got {sigma!r}")
