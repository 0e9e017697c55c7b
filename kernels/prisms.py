"""The raster's inputs from a scene: its prisms' projected vertices and face planes (``docs/architecture.md``,
"Rasterizer"); the Torch functions of ``warpskill.engine.primitives`` and ``warpskill.engine.projection`` are
their reference.

Per frame f and primitive k (k = 0 the hand, k >= 1 the cuboid k - 1), a convex n-prism (n = ``sides[k]``) has 2n
vertices, the bottom ring then the top ring. The hand's ring has circumradius ``radius`` about its axis (local +z)
at the axis range [t0, t1] kept in front of the near plane; a cuboid's corners are -+ size / 2 along its local axes.
With the camera at (0, 0, height), pitched down by ``elevation`` (camera-to-world rotation R), a world point p is
x = R^T (p - (0, 0, height)) in the camera and projects to (fx x / z + cx, fy y / z + cy) [px], z clamped to at
least ``_MIN_DEPTH``.

:func:`project` is differentiable: :func:`project_backward` runs its adjoint (Warp's reverse mode), taking the
gradients of the projected vertices to the poses, sizes and camera. :func:`face_planes` (forward only) writes the
planes facing the camera and whether each primitive is drawn.
"""

import functools
import math

import warp as wp

from . import OPTIMIZATION_LEVEL

_MIN_DEPTH = 1.0e-3
"""Depth [m] the projection's divisor is clamped to (vertices behind the near plane are not drawn anyway)."""


@functools.cache
def records(dtype):
    """The kernels' records for scalar type ``dtype``: (``Prisms``, ``Scene``) Warp struct types.

    ``Prisms``: each prism's ``sides`` (P,) int32, the hand prism's circumradius ``radius`` [m] and ``length`` [m],
    and the ``near`` plane [m]. ``Scene``: ``hand_pos`` (F,), ``hand_rot`` (F,), ``cuboid_pos``, ``cuboid_rot``,
    ``cuboid_size`` (F, C) and the camera's ``height`` [m] and ``elevation`` [rad] (1,); :func:`project`'s adjoint
    adds into their arrays' gradients.
    """
    vec3, mat33 = wp.types.vector(3, dtype), wp.types.matrix((3, 3), dtype)

    @wp.struct
    class Prisms:
        sides: wp.array(dtype=int)
        radius: dtype
        length: dtype
        near: dtype

    @wp.struct
    class Scene:
        hand_pos: wp.array(dtype=vec3)
        hand_rot: wp.array(dtype=mat33)
        cuboid_pos: wp.array2d(dtype=vec3)
        cuboid_rot: wp.array2d(dtype=mat33)
        cuboid_size: wp.array2d(dtype=vec3)
        height: wp.array(dtype=dtype)
        elevation: wp.array(dtype=dtype)

    return Prisms, Scene


@functools.cache
def _kernels(dtype, max_sides: int):
    """The projection and face-plane kernels for scalar type ``dtype`` and prisms of at most ``max_sides`` sides."""
    vec2, vec3, vec4 = (wp.types.vector(n, dtype) for n in (2, 3, 4))
    mat33 = wp.types.matrix((3, 3), dtype)
    vertices = wp.types.matrix((2 * max_sides, 3), dtype)  # a prism's vertices, one a row
    Prisms, Scene = records(dtype)
    two_pi = 2.0 * math.pi

    @wp.func
    def camera_rotation(elevation: dtype) -> mat33:
        """Camera-to-world rotation: columns the camera's x (right), y (down), z (forward) axes."""
        s, c = wp.sin(elevation), wp.cos(elevation)
        zero, one = dtype(0.0), dtype(1.0)
        return mat33(one, zero, zero, zero, -s, c, zero, -c, -s)

    @wp.func
    def hand_extent(pos: vec3, rot: mat33, height: dtype, forward: vec3, radius: dtype, length: dtype,
                    near: dtype) -> vec3:
        """(t0, t1, visible): the hand's axis range [m] whose rings keep depth >= near (1: some is in front)."""
        zero = dtype(0.0)
        tip = pos - vec3(zero, zero, height)
        slope = wp.dot(vec3(rot[0, 2], rot[1, 2], rot[2, 2]), forward)
        across_x = rot[0, 0] * forward[0] + rot[1, 0] * forward[1] + rot[2, 0] * forward[2]
        across_y = rot[0, 1] * forward[0] + rot[1, 1] * forward[1] + rot[2, 1] * forward[2]
        rho = wp.sqrt(across_x * across_x + across_y * across_y + dtype(1.0e-12))
        margin = wp.dot(tip, forward) - radius * rho - near
        safe = wp.where(wp.abs(slope) < dtype(1.0e-9), dtype(1.0e-9), slope)
        crossing = wp.clamp(-margin / safe, zero, length)
        t0 = wp.where(slope > zero, crossing, zero)
        t1 = wp.where(slope < zero, crossing, length)
        visible = wp.where(wp.max(margin, margin + length * slope) > zero and t1 - t0 > dtype(1.0e-6),
                           dtype(1.0), zero)
        return vec3(t0, t1, visible)

    @wp.func
    def corner(v: int) -> vec3:
        """Cuboid corner v (0..7) in units of half its size: the bottom ring, then the top ring."""
        q = v % 4
        one = dtype(1.0)
        return vec3(wp.where(q == 1 or q == 2, one, -one), wp.where(q >= 2, one, -one), wp.where(v >= 4, one, -one))

    @wp.func
    def hand_extent_in(prisms: Prisms, scene: Scene, f: int, height: dtype, R: mat33) -> vec3:
        """:func:`hand_extent` of the hand in frame f seen by a camera at ``height`` of rotation ``R``."""
        forward = vec3(R[0, 2], R[1, 2], R[2, 2])
        return hand_extent(scene.hand_pos[f], scene.hand_rot[f], height, forward, prisms.radius, prisms.length,
                           prisms.near)

    @wp.func
    def prism_frame(prisms: Prisms, scene: Scene, f: int, k: int, height: dtype, R: mat33) -> tuple[mat33, vec3, vec3]:
        """(axes, origin, shape) of primitive k in frame f: its vertex v is axes local(v) + origin in camera
        coordinates [m] (:func:`camera_vertex`); shape is the hand's (t0, t1, radius) or a cuboid's half size."""
        rot = mat33()
        pos = vec3()
        shape = vec3()
        if k == 0:
            extent = hand_extent_in(prisms, scene, f, height, R)
            rot = scene.hand_rot[f]
            pos = scene.hand_pos[f]
            shape = vec3(extent[0], extent[1], prisms.radius)
        else:
            rot = scene.cuboid_rot[f, k - 1]
            pos = scene.cuboid_pos[f, k - 1]
            shape = dtype(0.5) * scene.cuboid_size[f, k - 1]
        zero = dtype(0.0)
        to_camera = wp.transpose(R)
        return to_camera * rot, to_camera * (pos - vec3(zero, zero, height)), shape

    @wp.func
    def camera_vertex(k: int, v: int, n: int, axes: mat33, origin: vec3, shape: vec3) -> vec3:
        """Vertex v of primitive k (an n-prism; :func:`prism_frame`) in camera coordinates [m]."""
        local = wp.cw_mul(corner(v), shape)
        if k == 0:
            angle = dtype(v % n) * (dtype(two_pi) / dtype(n))
            local = vec3(shape[2] * wp.cos(angle), shape[2] * wp.sin(angle), wp.where(v < n, shape[0], shape[1]))
        return axes * local + origin

    @wp.kernel(module="unique", module_options={"optimization_level": OPTIMIZATION_LEVEL})
    def _project(
        # Model:
        prisms: Prisms,
        intrinsics: vec4,
        # Data in:
        scene: Scene,
        # Data out:
        pixel_out: wp.array3d(dtype=vec2),
    ):
        f, k = wp.tid()
        n = prisms.sides[k]
        axes, origin, shape = prism_frame(prisms, scene, f, k, scene.height[0], camera_rotation(scene.elevation[0]))
        for v in range(2 * n):  # nothing carried from one vertex to the next: the adjoint replays each
            x = camera_vertex(k, v, n, axes, origin, shape)
            z = wp.max(x[2], dtype(_MIN_DEPTH))
            pixel_out[f, k, v] = vec2(intrinsics[0] * x[0] / z + intrinsics[2],
                                      intrinsics[1] * x[1] / z + intrinsics[3])

    @wp.func
    def outward(normal: vec3, anchor: vec3, centre: vec3) -> vec4:
        """The plane (n, d) through ``anchor`` with normal n = +-``normal`` pointing away from ``centre``."""
        outer = normal * wp.sign(wp.dot(anchor - centre, normal))
        return vec4(outer[0], outer[1], outer[2], wp.dot(outer, anchor))

    @wp.kernel(module="unique", module_options={"optimization_level": OPTIMIZATION_LEVEL, "enable_backward": False})
    def _face_planes(
        # Model:
        prisms: Prisms,
        # Data in:
        scene: Scene,
        # Data out:
        plane_out: wp.array3d(dtype=vec4),
        plane_count_out: wp.array2d(dtype=int),
        visible_out: wp.array2d(dtype=int),
    ):
        f, k = wp.tid()
        n = prisms.sides[k]
        h = scene.height[0]
        R = camera_rotation(scene.elevation[0])
        axes, origin, shape = prism_frame(prisms, scene, f, k, h, R)
        x = vertices()
        centre = vec3()
        deepest = dtype(1.0e30)
        for v in range(2 * n):
            p = camera_vertex(k, v, n, axes, origin, shape)
            x[v] = p
            centre += p
            deepest = wp.min(deepest, p[2])
        centre = centre / dtype(2 * n)
        if k == 0:
            visible_out[f, k] = int(hand_extent_in(prisms, scene, f, h, R)[2])
        else:
            visible_out[f, k] = wp.where(deepest >= prisms.near, 1, 0)

        cap = wp.cross(x[1] - x[0], x[2] - x[0])
        count = int(0)
        for face in range(n + 2):  # the n sides, then the bottom and the top cap
            plane = vec4()
            if face < n:
                bottom = x[face]
                plane = outward(wp.cross(x[(face + 1) % n] - bottom, x[face + n] - bottom), bottom, centre)
            else:
                plane = outward(cap, x[wp.where(face == n, 0, n)], centre)
            if plane[3] < dtype(0.0):  # faces the camera: can hold a ray's entry
                plane_out[f, k, count] = plane
                count += 1
        for rest in range(count, plane_out.shape[2]):
            plane_out[f, k, rest] = vec4()
        plane_count_out[f, k] = count

    return _project, _face_planes


def project(prisms, intrinsics, scene, pixel: wp.array, pixel_grad: wp.array | None = None) -> None:
    """Projected vertices (F, P, V) [px] of every prism into ``pixel`` (left as they are beyond each one's
    2 ``sides[k]``).

    ``prisms``, ``scene``: the :func:`records` of the prisms and of the poses and camera; ``intrinsics`` is (fx, fy,
    cx, cy) [px]. With ``pixel_grad`` (dL/d``pixel``) it runs the adjoint instead, adding dL/d``scene`` into the
    gradients of its arrays.
    """
    kernel = _kernels(pixel.dtype._wp_scalar_type_, pixel.shape[2] // 2)[0]
    inputs = [prisms, intrinsics, scene]
    if pixel_grad is None:
        wp.launch(kernel, dim=pixel.shape[:2], inputs=inputs, outputs=[pixel], device=pixel.device)
        return
    no_adjoint = [type(prisms)(), type(intrinsics)(), type(scene)()]  # a struct's adjoint goes to its arrays' grads
    wp.launch(kernel, dim=pixel.shape[:2], inputs=inputs, outputs=[pixel], device=pixel.device, adj_inputs=no_adjoint,
              adj_outputs=[pixel_grad], adjoint=True)


def face_planes(prisms, scene, plane: wp.array, plane_count: wp.array, visible: wp.array) -> None:
    """The face planes (n, d) in camera coordinates (F, P, MAX_SIDES + 2) of every prism that face the camera
    (d < 0), in face order (the n sides, then the bottom and top caps), zeros after them, into ``plane``; their
    number (F, P) into ``plane_count``; 1 into ``visible`` (F, P) where a primitive is drawn (the hand: some of it
    in front of the near plane; a cuboid: every vertex). Arguments as :func:`project`."""
    kernel = _kernels(plane.dtype._wp_scalar_type_, plane.shape[2] - 2)[1]
    wp.launch(kernel, dim=plane_count.shape, inputs=[prisms, scene], outputs=[plane, plane_count, visible],
              device=plane.device)
