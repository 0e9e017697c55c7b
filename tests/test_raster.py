"""Tests of the soft-silhouette rasterizer against exact ray casting and dense references."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from device_support import torch_devices

from warpskill.contract.camera import Intrinsics
from warpskill.engine.primitives import (
    HAND_LENGTH,
    HAND_RADIUS,
    HAND_SEGMENTS,
    cuboid_vertices,
    hand_axis_extent,
    hand_vertices,
    prism_planes,
)
from warpskill.engine.raycast import raycast_masks
from warpskill.engine.rendering import _POOL, _SoftSilhouettes, raster, render_silhouettes, silhouette_profiles

HEIGHT, ELEVATION = 0.30, 0.50  # camera [m], [rad]
FULL = Intrinsics.default(240, 427)


def rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def hand_frame(axis, roll: float = 0.0) -> np.ndarray:
    """A hand rotation whose local +z (tip towards arm) is ``axis``."""
    z = np.asarray(axis, float) / np.linalg.norm(axis)
    x = np.cross([0.0, 0.0, 1.0] if abs(z[2]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z], axis=1)
    return R @ rot_z(roll)


def scene(hand, cuboids, frames: int = 3, drift=(0.01, 0.0, 0.005)) -> dict:
    """Scene arrays (float64 tensors) of ``frames`` frames; the hand drifts by ``drift`` per frame.

    hand: (tip, axis); cuboids: list of (centre, yaw, size).
    """
    tip, axis = hand
    centres = np.array([c for c, _, _ in cuboids])
    rotations = np.array([rot_z(yaw) for _, yaw, _ in cuboids])
    arrays = {
        "hand_pos": np.asarray(tip) + np.arange(frames)[:, None] * np.asarray(drift),
        "hand_rot": np.stack([hand_frame(axis, 0.1 * f) for f in range(frames)]),
        "cuboid_pos": np.repeat(centres[None], frames, axis=0),
        "cuboid_rot": np.repeat(rotations[None], frames, axis=0),
        "cuboid_size": np.array([size for _, _, size in cuboids]),
        "camera_height": np.array(HEIGHT),
        "camera_elevation": np.array(ELEVATION),
    }
    return {k: torch.tensor(v, dtype=torch.float64) for k, v in arrays.items()}


SCENES = {
    # The hand reaches over the object's front; a static cuboid stands beside and behind it.
    "hand_in_front": scene(
        ((-0.05, 0.45, 0.07), (0.1, -0.4, 1.0)),
        [((0.0, 0.55, 0.03), 0.4, (0.06, 0.06, 0.06)), ((0.12, 0.66, 0.05), -0.3, (0.12, 0.08, 0.10))],
    ),
    # The object stands partly behind a static cuboid; the hand is off to the side.
    "object_behind_static": scene(
        ((-0.16, 0.6, 0.12), (0.0, -0.3, 1.0)),
        [((0.03, 0.62, 0.04), 0.3, (0.08, 0.08, 0.08)), ((-0.01, 0.5, 0.05), 0.1, (0.2, 0.06, 0.1))],
    ),
    # The hand's tip is inside the object: the depth test decides the visible boundary.
    "tip_inside_object": scene(
        ((0.01, 0.56, 0.05), (0.3, -0.5, 1.0)),
        [((0.0, 0.55, 0.04), 0.2, (0.08, 0.08, 0.08))],
        drift=(0.0, 0.0, 0.01),
    ),
    # The arm runs back past the camera: the near plane clips it.
    "arm_towards_camera": scene(
        ((0.06, 0.30, 0.10), (0.5, -1.0, 0.25)),
        [((-0.04, 0.45, 0.03), 0.3, (0.06, 0.06, 0.06))],
    ),
}


def test_prisms_are_closed_and_outward():
    """Faces enclose every vertex (n . x <= d), and the hand prism has the cylinder's cross-section."""
    s = SCENES["hand_in_front"]
    hand = hand_vertices(s["hand_pos"], s["hand_rot"])
    cuboids = cuboid_vertices(s["cuboid_pos"], s["cuboid_rot"], s["cuboid_size"])
    for vertices in (hand, cuboids):
        planes = prism_planes(vertices)
        slack = vertices @ planes[..., :3].transpose(-1, -2) - planes[..., None, :, 3]
        assert float(slack.max()) < 1e-9
        assert bool((planes[..., :3].norm(dim=-1) > 0).all())
    ring = (hand[0, :HAND_SEGMENTS] - s["hand_pos"][0]) @ s["hand_rot"][0]  # local frame
    area = 0.5 * float((ring[:, 0] * torch.roll(ring[:, 1], -1) - ring[:, 1] * torch.roll(ring[:, 0], -1)).sum())
    assert abs(area - math.pi * HAND_RADIUS**2) < 1e-12
    assert torch.allclose(ring[:, 2], torch.zeros(HAND_SEGMENTS, dtype=torch.float64), atol=1e-12)


def numpy_scene(s: dict) -> dict:
    return {k: v.numpy() for k, v in s.items()}


def alone(s: dict, k: int) -> dict:
    """The scene with every primitive but k moved out of sight (k = 0 the hand)."""
    out = dict(s)
    if k != 0:
        out["hand_pos"] = s["hand_pos"] - np.array([0.0, 10.0, 0.0])  # behind the camera
    away = np.arange(s["cuboid_pos"].shape[1]) != k - 1
    out["cuboid_pos"] = s["cuboid_pos"] + 100.0 * away[None, :, None]
    return out


@pytest.mark.parametrize("name", sorted(SCENES))
def test_hard_masks_match_ray_casting(name):
    s = SCENES[name]
    with torch.no_grad():
        soft = render_silhouettes(**s, intrinsics=FULL, sigma=0.05)
    rendered = soft.numpy() > 0.5
    reference = raycast_masks(**numpy_scene(s), intrinsics=FULL)
    assert rendered.shape == reference.shape == (3, soft.shape[1], 240, 427)
    for k in range(soft.shape[1]):
        union = (rendered[:, k] | reference[:, k]).sum()
        iou = (rendered[:, k] & reference[:, k]).sum() / union
        assert union > 500, f"{name}: object {k} barely visible, the scene tests nothing"
        assert iou >= 0.99, f"{name}: object {k} IoU {iou:.4f} < 0.99"
    if name != "arm_towards_camera":  # the scene must hide parts of objects behind others
        hidden = sum(
            int(raycast_masks(**alone(numpy_scene(s), k), intrinsics=FULL)[:, k].sum() - reference[:, k].sum())
            for k in range(soft.shape[1])
        )
        assert hidden > 300, f"{name}: only {hidden} pixels occluded"


# Gradient check: parameters x perturb the scene "hand_in_front" (depth orders well separated).
GRAD_SCENE = scene(
    ((-0.045, 0.45, 0.07), (0.1, -0.4, 1.0)),
    [((0.0, 0.56, 0.03), 0.4, (0.06, 0.06, 0.06)), ((0.1, 0.68, 0.05), -0.3, (0.12, 0.08, 0.10))],
    frames=2,
)
GROUPS = {
    "hand_pos": slice(0, 3),
    "hand_rot": slice(3, 6),
    "cuboid_pos": slice(6, 12),
    "cuboid_rot": slice(12, 18),
    "cuboid_size": slice(18, 24),
    "camera": slice(24, 26),
}


def so3_exp(w: torch.Tensor) -> torch.Tensor:
    zero = torch.zeros((), dtype=w.dtype, device=w.device)
    W = torch.stack(
        [torch.stack([zero, -w[2], w[1]]), torch.stack([w[2], zero, -w[0]]), torch.stack([-w[1], w[0], zero])]
    )
    return torch.linalg.matrix_exp(W)


def perturbed_loss(x: torch.Tensor, weights: torch.Tensor, intrinsics: Intrinsics) -> torch.Tensor:
    s = {k: v.to(x.device) for k, v in GRAD_SCENE.items()}
    masks = render_silhouettes(
        s["hand_pos"] + x[0:3],
        so3_exp(x[3:6]) @ s["hand_rot"],
        s["cuboid_pos"] + x[6:12].view(1, 2, 3),
        torch.stack([so3_exp(x[12:15]), so3_exp(x[15:18])]) @ s["cuboid_rot"],
        s["cuboid_size"] + x[18:24].view(2, 3),
        s["camera_height"] + x[24],
        s["camera_elevation"] + x[25],
        intrinsics,
        sigma=1.0,
    )
    return (masks * weights).sum()


@pytest.mark.slow
@pytest.mark.parametrize("device", torch_devices())
def test_gradients_match_finite_differences(device):
    intrinsics = FULL
    H, W = intrinsics.image_size
    weights = torch.rand(2, 3, H, W, generator=torch.Generator().manual_seed(0), dtype=torch.float64).to(device)
    x = torch.zeros(26, dtype=torch.float64, requires_grad=True, device=device)
    perturbed_loss(x, weights, intrinsics).backward()
    eps = 3e-4  # [m] and [rad]: ~0.1 px image motion
    fd = torch.zeros(26, dtype=torch.float64, device=device)
    with torch.no_grad():
        for i in range(26):
            d = torch.zeros(26, dtype=torch.float64, device=device)
            d[i] = eps
            fd[i] = (perturbed_loss(d, weights, intrinsics) - perturbed_loss(-d, weights, intrinsics)) / (2 * eps)
    for group, idx in GROUPS.items():
        g, f = x.grad[idx], fd[idx]
        error = float((g - f).norm() / f.norm())
        # The loss is only piecewise smooth (max over edge lines, hull changes): a few pixels
        # sit on kinks within the finite-difference step, hence a 1 % tolerance.
        assert error < 0.01, f"{group}: relative error {error:.4f} >= 0.01 (autograd {g}, finite differences {f})"


# --- Dense reference: the same forward in plain Torch, differentiated by autograd. ---


def convex_hull(points: np.ndarray) -> list[int]:
    """Counter-clockwise hull indices (Andrew's monotone chain)."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))

    def chain(indices):
        out = []
        for i in indices:
            while len(out) >= 2:
                o, a, b = points[out[-2]], points[out[-1]], points[i]
                if (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]) > 0:
                    break
                out.pop()
            out.append(i)
        return out[:-1]

    return chain(order) + chain(order[::-1])


def dense_masks(pixels, planes, sides, K, image_size, sigma, cut=True):
    """Visible masks (F, P, H, W) without tiles or moments (with ``cut``, coverage cut off as
    the kernels cut it: exactly 0 or 1 beyond +-CUTOFF sigma)."""
    F, P = pixels.shape[:2]
    H, W = image_size
    v, u = torch.meshgrid(torch.arange(H) + 0.5, torch.arange(W) + 0.5, indexing="ij")
    p = torch.stack([u, v], -1).reshape(-1, 2).to(pixels)
    masks = []
    for f in range(F):
        cs, zs = [], []
        for k in range(P):
            idx = convex_hull(pixels[f, k, : 2 * sides[k]].detach().numpy())
            a = pixels[f, k, idx]
            e = torch.roll(a, -1, 0) - a
            normal = torch.stack([e[:, 1], -e[:, 0]], -1) / e.norm(dim=-1, keepdim=True)
            sd = ((p[:, None] - a[None]) * normal[None]).sum(-1).max(-1).values
            limit = raster.CUTOFF * sigma if cut else float("inf")
            cs.append(torch.where(sd.abs() <= limit, torch.sigmoid(-sd / sigma), (sd < 0).to(sd)))
            with torch.no_grad():  # depth at the pixel, or at the nearest hull point outside
                s = (((p[:, None] - a[None]) * e[None]).sum(-1) / (e**2).sum(-1)).clamp(0, 1)
                foot = a[None] + s[..., None] * e[None]
                nearest = foot[torch.arange(len(p)), (p[:, None] - foot).norm(dim=-1).argmin(-1)]
                q = torch.where((sd > 0)[:, None], nearest, p)
                ray = torch.stack([(q[:, 0] - K[0, 2]) / K[0, 0], (q[:, 1] - K[1, 2]) / K[1, 1], torch.ones_like(q[:, 0])], -1)
                nr = ray @ planes[f, k, :, :3].T
                t = torch.where(nr < 0, planes[f, k, :, 3] / nr, torch.full_like(nr, -1e30))
                zs.append(t.max(-1).values)
        for k in range(P):
            T = torch.ones(len(p), dtype=pixels.dtype)
            for m in range(P):
                if m != k:
                    front = (zs[m] < zs[k]) | ((zs[m] == zs[k]) & (m < k))
                    T = T * torch.where(front, 1 - cs[m], torch.ones_like(T))
            masks.append(cs[k] * T)
    return torch.stack(masks).view(F, P, H, W)


def projected_scene(s: dict, intrinsics: Intrinsics):
    """Projected vertices (F, P, 48, 2), camera-frame planes (F, P, 26, 4) and sides of a scene."""
    from warpskill.engine.projection import project, world_to_camera

    h, e = s["camera_height"], s["camera_elevation"]
    cams = [
        world_to_camera(hand_vertices(s["hand_pos"], s["hand_rot"]), h, e).unsqueeze(1),
        world_to_camera(cuboid_vertices(s["cuboid_pos"], s["cuboid_rot"], s["cuboid_size"]), h, e),
    ]
    pixels = torch.cat([_pad(project(c, intrinsics.K), 48) for c in cams], dim=1)
    planes = _camera_facing(torch.cat([_pad(prism_planes(c), 26) for c in cams], dim=1))
    sides = [HAND_SEGMENTS] + [4] * s["cuboid_pos"].shape[1]
    return pixels.detach(), planes, sides


def _camera_facing(planes: torch.Tensor) -> torch.Tensor:
    """Move the faces that see the camera (d < 0) first; the others (zeroed) cannot hold a ray's entry."""
    facing = planes[..., 3:] < 0
    order = torch.argsort((~facing[..., 0]).to(torch.int8), dim=-1, stable=True)
    return torch.gather(planes * facing, -2, order.unsqueeze(-1).expand_as(planes))


def _pad(x: torch.Tensor, rows: int) -> torch.Tensor:
    """Zero-pad dimension -2 of x to ``rows``."""
    return torch.nn.functional.pad(x, (0, 0, 0, rows - x.shape[-2]))


@pytest.fixture(scope="module")
def dense_case():
    """A tiny image (48 x 86) of overlapping soft layers, with the dense reference's gradients."""
    intrinsics = FULL.resized(48, 86)
    s = {**GRAD_SCENE, "cuboid_pos": GRAD_SCENE["cuboid_pos"] - torch.tensor([0.0, 0.02, 0.0], dtype=torch.float64)}
    pixels, planes, sides = projected_scene(s, intrinsics)
    F, P = pixels.shape[:2]
    H, W = intrinsics.image_size
    K = torch.as_tensor(intrinsics.K)
    case = {
        "pixels": pixels,
        "planes": planes,
        "sides": torch.tensor(sides, dtype=torch.int32),
        "visible": torch.ones(F, P, dtype=torch.bool),
        "camera_vec": (float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])),
        "image_size": (H, W),
        "sigma": 1.5,
        "weights": torch.rand(F, P, H, W, generator=torch.Generator().manual_seed(1), dtype=torch.float64),
    }
    dense = pixels.clone().requires_grad_(True)
    masks = dense_masks(dense, planes, sides, K, (H, W), case["sigma"])
    (masks * case["weights"]).sum().backward()
    case.update(dense_masks=masks.detach(), dense_grad=dense.grad)
    assert int(((case["dense_masks"] > 0.01).sum(dim=1) >= 2).sum()) > 20, "the case must overlap soft layers"
    return case


def test_vertex_gradients_match_dense_reference(dense_case):
    c = dense_case
    ours = c["pixels"].clone().requires_grad_(True)
    masks, *_ = _SoftSilhouettes.apply(
        ours, c["planes"], c["visible"], c["sides"], c["camera_vec"], c["image_size"], c["sigma"], None, None
    )
    (masks.double() * c["weights"]).sum().backward()
    assert float((masks.detach().double() - c["dense_masks"]).abs().max()) < 2e-5  # float32
    rel = float((ours.grad - c["dense_grad"]).norm() / c["dense_grad"].norm())
    assert rel < 3e-4, f"vertex gradients differ from the dense reference by {rel:.2e}"  # float32 kernels


@pytest.mark.parametrize("threads", [3, raster.TILE], ids=["3 threads", "a thread per row"])
def test_threads_sharing_a_tiles_rows_draw_what_one_thread_draws(dense_case, threads, monkeypatch):
    # A GPU gives each row of a tile its own thread; a share of rows per thread must draw the
    # same masks, profiles and gradients as one thread per tile (to float32 summation order).
    c = dense_case
    F, P = c["pixels"].shape[:2]
    targets = (torch.rand(F, P, *c["image_size"], generator=torch.Generator().manual_seed(7)) > 0.5).float()

    def draw() -> list[torch.Tensor]:
        results = []
        for along in (None, targets):
            ours = c["pixels"].clone().requires_grad_(True)
            outputs = _SoftSilhouettes.apply(ours, c["planes"], c["visible"], c["sides"], c["camera_vec"],
                                             c["image_size"], c["sigma"], along, None if along is None else torch.arange(F))
            outputs = [out for out in outputs if out is not None]
            weights = torch.Generator().manual_seed(8)
            sum((out.double() * torch.rand(out.shape, generator=weights, dtype=torch.float64)).sum()
                for out in outputs).backward()  # fmt: skip
            results += [out.detach() for out in outputs] + [ours.grad]
        return results

    alone = draw()
    monkeypatch.setattr(raster, "lanes", lambda device: threads)
    for shared, one in zip(draw(), alone, strict=True):
        torch.testing.assert_close(shared.double(), one.double(), rtol=1e-5, atol=1e-5)


def test_cut_off_drops_at_most_the_sigmoid_tail(dense_case):
    # Against soft layers never cut off, the kernels' masks differ by at most the coverage
    # the cut-off drops, sigmoid(-CUTOFF) per layer (a pixel in two bands: twice that).
    c = dense_case
    K = torch.as_tensor(FULL.resized(*c["image_size"]).K)
    with torch.no_grad():
        uncut = dense_masks(c["pixels"], c["planes"], c["sides"], K, c["image_size"], c["sigma"], cut=False)
        masks, *_ = _SoftSilhouettes.apply(
            c["pixels"], c["planes"], c["visible"], c["sides"], c["camera_vec"], c["image_size"], c["sigma"], None, None
        )
    tail = 1.0 / (1.0 + math.exp(raster.CUTOFF))
    gap = float((masks.double() - uncut).abs().max())
    assert 0.1 * tail < gap < 2 * tail + 2e-5, f"cut-off changed a mask by {gap:.2e} (tail {tail:.2e})"


def test_profiles_match_the_dense_masks_sums_and_gradients(dense_case):
    # The profiles (row sums, column sums, overlap with a target) without forming the masks,
    # against the dense reference's masks; their gradients against the dense reference's for
    # the same loss, whose per-pixel weight is w_row[i] + w_col[j] + w_overlap t_ij.
    c = dense_case
    F, P = c["pixels"].shape[:2]
    H, W = c["image_size"]
    gen = torch.Generator().manual_seed(2)
    targets = (torch.rand(F, P, H, W, generator=gen) > 0.5).float()
    w_rows, w_cols, w_overlap = (torch.rand(F, P, n, generator=gen, dtype=torch.float64) for n in (H, W, 1))
    ours = c["pixels"].clone().requires_grad_(True)
    _, rows, cols, overlap = _SoftSilhouettes.apply(
        ours, c["planes"], c["visible"], c["sides"], c["camera_vec"], c["image_size"], c["sigma"],
        targets, torch.arange(F),
    )
    dense = c["dense_masks"]
    assert float((rows.detach().double() - dense.sum(-1)).abs().max()) < 1e-3
    assert float((cols.detach().double() - dense.sum(-2)).abs().max()) < 1e-3
    assert float((overlap.detach().double() - (dense * targets).sum((-1, -2))).abs().max()) < 1e-2
    loss = (rows.double() * w_rows).sum() + (cols.double() * w_cols).sum() + (overlap.double() * w_overlap[..., 0]).sum()
    loss.backward()
    reference = c["pixels"].clone().requires_grad_(True)
    masks = dense_masks(reference, c["planes"], c["sides"], torch.as_tensor(FULL.resized(H, W).K), (H, W), c["sigma"])
    weights = w_rows[..., :, None] + w_cols[..., None, :] + w_overlap[..., None] * targets.double()
    (masks * weights).sum().backward()
    rel = float((ours.grad - reference.grad).norm() / reference.grad.norm())
    assert rel < 3e-4, f"profile gradients differ from the dense reference by {rel:.2e}"


def test_profiles_read_each_frames_own_target_frame():
    # Three frames that share one target frame (as hypotheses of one video share a video's
    # targets) give the profiles of the three frames with that target repeated.
    s = SCENES["hand_in_front"]
    intrinsics = FULL.scaled(0.25)
    H, W = intrinsics.image_size
    targets = (torch.rand(1, 3, H, W, generator=torch.Generator().manual_seed(3)) > 0.3).float()
    poses = {k: v.float() for k, v in s.items()}
    shared = silhouette_profiles(**poses, intrinsics=intrinsics, targets=targets,
                                 target_frame=torch.zeros(3, dtype=torch.long), sigma=1.0)
    repeated = silhouette_profiles(**poses, intrinsics=intrinsics, targets=targets.expand(3, -1, -1, -1), sigma=1.0)
    masks = render_silhouettes(**poses, intrinsics=intrinsics, sigma=1.0)
    for a, b in zip(shared, repeated):
        torch.testing.assert_close(a, b, rtol=0, atol=0)
    torch.testing.assert_close(shared[2], (masks * targets).sum((-1, -2)), rtol=1e-5, atol=1e-3)
    with pytest.raises(ValueError, match="target_frame"):
        silhouette_profiles(**poses, intrinsics=intrinsics, targets=targets, sigma=1.0)  # 3 frames, 1 target


def test_empty_and_offscreen_give_zeros_and_finite_gradients():
    s = {k: v.clone() for k, v in SCENES["hand_in_front"].items()}
    s["hand_pos"] = s["hand_pos"] - torch.tensor([0.0, 2.0, 0.0], dtype=torch.float64)  # behind the camera
    s["cuboid_pos"] = s["cuboid_pos"] + torch.tensor([5.0, 0.0, 0.0], dtype=torch.float64)  # far off to the right
    leaves = {k: v.requires_grad_(True) for k, v in s.items()}
    masks = render_silhouettes(**leaves, intrinsics=FULL.scaled(0.25), sigma=1.0)
    assert masks.shape == (3, 3, 60, 107)
    assert float(masks.detach().abs().max()) == 0.0
    masks.sum().backward()
    for name, t in leaves.items():
        assert t.grad is None or torch.isfinite(t.grad).all(), name

    # No cuboids at all, and a hand that reaches back past the camera (clipped, finite).
    s = SCENES["arm_towards_camera"]
    _, t1, visible = hand_axis_extent(s["hand_pos"], s["hand_rot"], s["camera_height"], s["camera_elevation"])
    assert visible.all() and (t1 < HAND_LENGTH - 0.05).all(), "the near plane must clip this arm by 5 cm or more"
    none = {**s, "cuboid_pos": s["cuboid_pos"][:, :0], "cuboid_rot": s["cuboid_rot"][:, :0]}
    none["cuboid_size"] = s["cuboid_size"][:0]
    pos = none["hand_pos"].clone().requires_grad_(True)
    masks = render_silhouettes(**{**none, "hand_pos": pos}, intrinsics=FULL.scaled(0.25))
    assert masks.shape == (3, 1, 60, 107) and float(masks.detach().max()) > 0.5
    masks.sum().backward()
    assert torch.isfinite(pos.grad).all() and float(pos.grad.abs().sum()) > 0


def test_invalid_inputs_raise_value_errors():
    s = SCENES["hand_in_front"]
    with pytest.raises(ValueError, match="hand_rot"):
        render_silhouettes(**{**s, "hand_rot": s["hand_rot"][:, :2]}, intrinsics=FULL)
    with pytest.raises(ValueError, match="cuboid_size"):
        render_silhouettes(**{**s, "cuboid_size": s["cuboid_size"][:1]}, intrinsics=FULL)
    with pytest.raises(ValueError, match="sigma"):
        render_silhouettes(**s, intrinsics=FULL, sigma=0.0)
    with pytest.raises(ValueError, match="camera_height"):
        render_silhouettes(**{**s, "camera_height": torch.ones(2, dtype=torch.float64)}, intrinsics=FULL)


def test_the_workspace_is_reused_and_never_shared_by_pending_backward_passes():
    intrinsics = FULL.resized(30, 53)
    targets = torch.rand(3, 3, 30, 53, generator=torch.Generator().manual_seed(5))
    near, far = ({k: v.float() for k, v in SCENES[name].items()} for name in ("hand_in_front", "object_behind_static"))

    def gradient(*scenes):  # of each scene's profile loss, all forward passes first
        tips = [s["hand_pos"].clone().requires_grad_(True) for s in scenes]
        losses = [sum(p.sum() for p in silhouette_profiles(**(s | {"hand_pos": tip}), intrinsics=intrinsics,
                                                            targets=targets, sigma=1.0))
                  for s, tip in zip(scenes, tips)]
        return [torch.autograd.grad(loss, tip)[0] for loss, tip in zip(losses, tips)]

    [alone] = gradient(near)
    together, _ = gradient(near, far)  # the second forward pass ran before the first backward pass
    torch.testing.assert_close(together, alone, rtol=0, atol=0)
    free = _POOL.free[next(key for key in _POOL.free if key[2] == (30, 53) and key[4])]  # profiles' workspaces
    assert len(free) == 2
    kept = list(free)
    gradient(near)
    assert len(free) == 2 and all(any(w is k for k in kept) for w in free)  # reused, none made


def test_a_workspace_left_by_another_scene_gives_what_a_fresh_one_gives():
    # The raster's buffers are never cleared between calls: a call must read back only what it
    # wrote itself, whatever a call of the same shape with other layers and bands left there.
    intrinsics = FULL.resized(30, 53)
    gen = torch.Generator().manual_seed(6)
    targets = torch.rand(3, 3, 30, 53, generator=gen)
    weights = [torch.rand(3, 3, n, generator=gen) for n in (30, 53)] + [torch.rand(3, 3, generator=gen)]
    near, far = ({k: v.float() for k, v in SCENES[name].items()} for name in ("hand_in_front", "object_behind_static"))

    def draw(scene):  # profiles, their loss's gradient, then the masks' gradient
        tip = scene["hand_pos"].clone().requires_grad_(True)
        profiles = silhouette_profiles(**(scene | {"hand_pos": tip}), intrinsics=intrinsics, targets=targets)
        (profile_grad,) = torch.autograd.grad(sum((p * w).sum() for p, w in zip(profiles, weights)), tip)
        masks = render_silhouettes(**(scene | {"hand_pos": tip}), intrinsics=intrinsics)
        (mask_grad,) = torch.autograd.grad((masks * targets).sum(), tip)
        return [p.detach() for p in profiles] + [masks.detach(), profile_grad, mask_grad]

    _POOL.free.clear()
    fresh = draw(near)
    kept = [w for free in _POOL.free.values() for w in free]
    draw(far)
    again = draw(near)
    assert all(any(w is k for k in kept) for free in _POOL.free.values() for w in free)  # the same buffers
    for first, second in zip(fresh, again):
        torch.testing.assert_close(second, first, rtol=0, atol=0)
