"""The prism kernels (``warpskill.kernels.prisms``) against the Torch primitives and projection they replace in the
raster's input, values and gradients, and their adjoint against central finite differences, on every device."""

from __future__ import annotations

import pytest
import torch
from device_support import torch_devices
from test_raster import FULL, SCENES

from warpskill.engine.primitives import (
    HAND_SEGMENTS,
    NEAR_PLANE,
    cuboid_vertices,
    hand_axis_extent,
    hand_vertices,
    prism_planes,
)
from warpskill.engine.projection import project, world_to_camera
from warpskill.engine.rendering import _raster_inputs

NAMES = ("hand_pos", "hand_rot", "cuboid_pos", "cuboid_rot", "cuboid_size", "camera_height", "camera_elevation")


def torch_prisms(s: dict, intrinsics) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Projected vertices (F, P, 48, 2), camera-facing planes first (F, P, 26, 4) and visibility (F, P) composed
    of the Torch primitives."""
    h, e = s["camera_height"], s["camera_elevation"]
    F, C = s["cuboid_pos"].shape[:2]
    t0, t1, hand_visible = hand_axis_extent(s["hand_pos"], s["hand_rot"], h, e)
    hand = world_to_camera(hand_vertices(s["hand_pos"], s["hand_rot"], extent=(t0, t1)), h, e).unsqueeze(1)
    cuboids = world_to_camera(cuboid_vertices(s["cuboid_pos"], s["cuboid_rot"], s["cuboid_size"].expand(F, C, 3)),
                              h, e)
    pad = lambda x, rows: torch.nn.functional.pad(x, (0, 0, 0, rows - x.shape[-2]))  # noqa: E731
    pixels = torch.cat([pad(project(v, intrinsics.K), 48) for v in (hand, cuboids)], dim=1)
    planes = torch.cat([pad(prism_planes(v.detach()), 26) for v in (hand, cuboids)], dim=1)
    facing = planes[..., 3:] < 0
    order = torch.argsort((~facing[..., 0]).to(torch.int8), dim=-1, stable=True)
    planes = torch.gather(planes * facing, -2, order.unsqueeze(-1).expand_as(planes))
    visible = torch.cat([hand_visible.unsqueeze(1), (cuboids[..., 2] >= NEAR_PLANE).all(dim=-1)], dim=1)
    return pixels, planes, visible


def kernel_prisms(s: dict, intrinsics) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    pixels, planes, visible, sides, _, _ = _raster_inputs(*(s[k] for k in NAMES), intrinsics)
    assert sides.tolist() == [HAND_SEGMENTS] + [4] * s["cuboid_pos"].shape[1]
    return pixels, planes, visible


def leaves(s: dict, device: str, dtype: torch.dtype) -> dict:
    return {k: v.to(device=device, dtype=dtype).clone().requires_grad_(True) for k, v in s.items()}


@pytest.mark.parametrize("device", torch_devices())
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
@pytest.mark.parametrize("name", sorted(SCENES))
def test_values_and_gradients_match_the_torch_primitives(name, dtype, device):
    weights = torch.randn(3, 1 + SCENES[name]["cuboid_pos"].shape[1], 48, 2, generator=torch.Generator().manual_seed(0),
                          dtype=dtype).to(device)
    results = []
    for prisms in (kernel_prisms, torch_prisms):
        s = leaves(SCENES[name], device, dtype)
        pixels, planes, visible = prisms(s, FULL)
        (pixels * weights).sum().backward()
        results.append((pixels.detach(), planes, visible, {k: s[k].grad for k in NAMES}))
    (pixels, planes, visible, grads), (ref_pixels, ref_planes, ref_visible, ref_grads) = results
    tol = 1e-9 if dtype == torch.float64 else 2e-4  # float32 rounds differently in the kernel
    assert torch.equal(visible, ref_visible)
    assert float((pixels - ref_pixels).abs().max()) < tol * 1e3  # [px]
    assert float((planes - ref_planes).abs().max() / ref_planes.abs().max()) < tol
    if name == "arm_towards_camera":
        assert not bool(planes[:, 0, :, :3].norm(dim=-1).eq(0).all()), "the clipped hand must still have faces"
    for k in NAMES:
        error = float((grads[k] - ref_grads[k]).norm() / ref_grads[k].norm())
        assert error < tol * 10, f"{k}: relative difference {error:.1e}"


@pytest.mark.parametrize("device", torch_devices())
@pytest.mark.parametrize("name", ["arm_towards_camera", "hand_in_front"])
def test_gradients_match_central_finite_differences(name, device):
    """Every input's gradient of a random projection of the vertices (float64), the hand clipped by the near plane
    in one scene and not in the other."""
    s = leaves(SCENES[name], device, torch.float64)
    weights = torch.randn(3, 1 + s["cuboid_pos"].shape[1], 48, 2, generator=torch.Generator().manual_seed(1),
                          dtype=torch.float64).to(device)
    loss = lambda: float((_raster_inputs(*(s[k] for k in NAMES), FULL)[0] * weights).sum())  # noqa: E731
    (_raster_inputs(*(s[k] for k in NAMES), FULL)[0] * weights).sum().backward()
    eps = 1e-6
    for k in NAMES:
        fd = torch.zeros_like(s[k])
        with torch.no_grad():
            for i in range(s[k].numel()):
                s[k].view(-1)[i] += eps
                up = loss()
                s[k].view(-1)[i] -= 2 * eps
                fd.view(-1)[i] = (up - loss()) / (2 * eps)
                s[k].view(-1)[i] += eps
        error = float((s[k].grad - fd).norm() / fd.norm())
        assert error < 1e-6, f"{k}: relative error {error:.1e} (adjoint {s[k].grad}, finite differences {fd})"
