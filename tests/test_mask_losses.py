"""The mask-loss kernels (``warpskill.kernels.mask_losses``, through :func:`~warpskill.optimizer.losses.masks_loss`)
against their Torch reference in ``warpskill.optimizer.losses``, values and gradients, and against central finite
differences, on every device; empty renderings and targets included."""

from __future__ import annotations

import pytest
import torch
from device_support import torch_devices

from warpskill.optimizer.losses import MaskProfile, MaskTargets, _box, _diou, _hidden, masks_loss


def case(device: str, dtype: torch.dtype) -> tuple[torch.Tensor, MaskTargets]:
    """Rendered masks (4, 3, 9, 11) and targets: channel 0 dIoU, 1 boxes, 2 dIoU; frame 3's channel 2 absent;
    an empty target (frame 1, channel 0), an empty rendering (frame 2, channel 2), an empty pair (frame 0,
    channel 2), a boxed target with a box along u only (frame 2, channel 1). Rendered values stay away from
    0.5, where the boxes jump."""
    gen = torch.Generator().manual_seed(3)
    target = torch.zeros(4, 3, 9, 11, dtype=dtype)
    for n in range(4):
        for c in range(3):
            r, s = torch.randint(0, 4, (2,), generator=gen).tolist()
            target[n, c, r : r + 4, s : s + 5] = 1.0
    target[1, 0] = 0.0
    target[0, 2] = 0.0
    target[2, 1] = 0.0
    target[2, 1, :, 5] = 0.3  # a faint column: a box in u, none in v (no row holds half a pixel)
    absent = torch.zeros(4, 3, dtype=torch.bool)
    absent[3, 2] = True
    rendered = torch.rand(4, 3, 9, 11, generator=gen, dtype=dtype)
    rendered = torch.where(rendered > 0.5, 0.6 + 0.3 * rendered, 0.4 * rendered)
    rendered[2, 2] = 0.0
    rendered[0, 2] = 0.0
    targets = MaskTargets(target.to(device), boxed=torch.tensor([False, True, False], device=device),
                          absent=absent.to(device))
    return rendered.to(device).requires_grad_(True), targets


def reference(rendered: torch.Tensor, targets: MaskTargets) -> torch.Tensor:
    """The per-mask loss composed of the Torch functions."""
    profile = MaskProfile.of(rendered, targets)
    per_mask = torch.where(targets.boxed, _box(profile, targets), _diou(profile, targets))
    return torch.where(targets.absent, _hidden(profile, targets), per_mask)


@pytest.mark.parametrize("device", torch_devices())
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_values_and_gradients_match_the_torch_reference(dtype, device):
    weights = torch.randn(4, 3, generator=torch.Generator().manual_seed(4), dtype=dtype).to(device)
    results = []
    for loss_of in (masks_loss, reference):
        rendered, targets = case(device, dtype)
        loss = loss_of(rendered, targets)
        (loss * weights).sum().backward()
        results.append((loss.detach(), rendered.grad))
    (loss, grad), (ref_loss, ref_grad) = results
    tol = 1e-12 if dtype == torch.float64 else 1e-5
    assert loss[0, 2] == 0.0 and loss[1, 0] == 0.0 and loss[2, 2] == 2.0  # empty target, empty rendering
    assert torch.isfinite(loss).all() and torch.isfinite(grad).all()
    assert torch.allclose(loss, ref_loss, rtol=tol, atol=tol)
    assert float((grad - ref_grad).norm() / ref_grad.norm()) < tol * 10


@pytest.mark.parametrize("device", torch_devices())
def test_gradients_match_central_finite_differences(device):
    rendered, targets = case(device, torch.float64)
    assert torch.autograd.gradcheck(lambda r: masks_loss(r, targets), (rendered,), eps=1e-6, atol=1e-6)


def test_a_second_backward_pass_gives_the_same_gradient():
    rendered, targets = case("cpu", torch.float64)
    loss = masks_loss(rendered, targets).sum()
    first = torch.autograd.grad(loss, rendered, retain_graph=True)[0]
    assert torch.equal(torch.autograd.grad(loss, rendered)[0], first)
