"""dIoU loss: values against a direct NumPy computation, gradients, empty masks."""

import numpy as np
import pytest
import torch

from warpskill.optimizer.losses import diou_loss


def _numpy_diou(a: np.ndarray, b: np.ndarray) -> float:
    """dIoU of two hard masks, computed directly from the definition."""
    inter = np.logical_and(a, b).sum()
    union = np.logical_or(a, b).sum()
    ia, ja = np.nonzero(a)
    ib, jb = np.nonzero(b)
    ca = np.array([ja.mean() + 0.5, ia.mean() + 0.5])
    cb = np.array([jb.mean() + 0.5, ib.mean() + 0.5])
    i_all, j_all = np.concatenate([ia, ib]), np.concatenate([ja, jb])
    diag2 = (j_all.max() + 1 - j_all.min()) ** 2 + (i_all.max() + 1 - i_all.min()) ** 2
    return 1 - inter / union + min(((ca - cb) ** 2).sum() / diag2, 1.0)


def _box(h, w, top, left, bottom, right):
    m = np.zeros((h, w), bool)
    m[top:bottom, left:right] = True
    return m


@pytest.mark.parametrize(
    "box_a, box_b",
    [((2, 3, 10, 12), (2, 3, 10, 12)), ((2, 3, 10, 12), (5, 8, 14, 20)), ((0, 0, 4, 4), (12, 18, 16, 24))],
)
def test_hard_masks_match_definition(box_a, box_b):
    a, b = _box(16, 24, *box_a), _box(16, 24, *box_b)
    loss, valid = diou_loss(torch.tensor(a, dtype=torch.float64), torch.tensor(b, dtype=torch.float64))
    assert bool(valid)
    assert float(loss) == pytest.approx(_numpy_diou(a, b), abs=1e-12)


def test_identical_masks_have_zero_loss_and_disjoint_ones_more_than_one():
    a = _box(16, 24, 2, 3, 10, 12)
    same, _ = diou_loss(torch.tensor(a, dtype=torch.float32), torch.tensor(a, dtype=torch.float32))
    apart, _ = diou_loss(torch.tensor(a, dtype=torch.float32), torch.tensor(_box(16, 24, 11, 14, 16, 24), dtype=torch.float32))
    assert float(same) == pytest.approx(0.0, abs=1e-6)
    assert float(apart) > 1.0


def test_empty_target_is_invalid_and_empty_rendering_is_maximal():
    target = torch.zeros(2, 8, 8, dtype=torch.float64)
    target[1, 2:5, 2:5] = 1.0
    rendered = torch.zeros(2, 8, 8, dtype=torch.float64, requires_grad=True)
    loss, valid = diou_loss(rendered, target)
    assert valid.tolist() == [False, True]
    assert loss.tolist() == [0.0, 2.0]
    loss.sum().backward()
    assert torch.isfinite(rendered.grad).all()


def test_gradient_matches_finite_differences():
    gen = torch.Generator().manual_seed(0)
    rendered = torch.rand(3, 6, 7, generator=gen, dtype=torch.float64, requires_grad=True)
    target = (torch.rand(3, 6, 7, generator=gen, dtype=torch.float64) > 0.5).double()
    # The enclosing box is piecewise constant: keep rendered values away from 0.5.
    with torch.no_grad():
        rendered.copy_(torch.where(rendered > 0.5, 0.6 + 0.3 * rendered, 0.4 * rendered))
    assert torch.autograd.gradcheck(lambda r: diou_loss(r, target)[0], (rendered,), eps=1e-6, atol=1e-7)


def test_masks_loss_picks_each_channels_loss_and_its_gradient_matches_finite_differences():
    from warpskill.optimizer.losses import MaskTargets, box_loss, hidden_loss, masks_loss

    gen = torch.Generator().manual_seed(1)
    target = torch.zeros(3, 2, 6, 7, dtype=torch.float64)
    target[:2, :, 1:4, 2:6] = 1.0  # both channels seen in frames 0-1; the object hidden in frame 2
    target[2, 0, 2:5, 1:3] = 1.0
    absent = torch.tensor([[False, False], [False, False], [False, True]])
    targets = MaskTargets(target, boxed=torch.tensor([False, True]), absent=absent)
    rendered = torch.rand(3, 2, 6, 7, generator=gen, dtype=torch.float64)
    with torch.no_grad():  # away from 0.5, where the enclosing boxes jump
        rendered.copy_(torch.where(rendered > 0.5, 0.6 + 0.3 * rendered, 0.4 * rendered))
    rendered.requires_grad_()
    loss = masks_loss(rendered, targets)
    close = lambda a, b: torch.allclose(a, b, rtol=1e-12, atol=0.0)  # noqa: E731 (Warp kernels against Torch)
    assert close(loss[:, 0], diou_loss(rendered[:, 0], target[:, 0])[0])
    assert close(loss[:2, 1], box_loss(rendered, targets)[:2, 1])
    assert close(loss[2, 1], hidden_loss(rendered, targets)[2, 1])
    assert torch.autograd.gradcheck(lambda r: masks_loss(r, targets), (rendered,), eps=1e-6, atol=1e-6)


def test_masks_of_another_shape_than_the_targets_are_refused():
    from warpskill.optimizer.losses import MaskTargets, masks_loss

    with pytest.raises(ValueError, match="differ in shape"):
        masks_loss(torch.zeros(2, 2, 6, 7), MaskTargets(torch.zeros(2, 2, 6, 8)))
