"""Benchmarks behind ``warpskill bench``: kernel microbenchmarks and the synthetic success table."""

from __future__ import annotations

import numpy as np
import torch

from warpskill.bench.report import show
from warpskill.bench.timing import timed
from warpskill.contract.camera import Intrinsics
from warpskill.engine.simulation import simulate
from warpskill.optimizer.scene import SceneTrajectories, render_scene
from warpskill.synthetic import make_demonstration, scripted_inputs, scripted_scene


def bench_kernels(device: str = "cpu", repeats: int = 5) -> list[dict]:
    """Time the physics rollout and the rasterizer, forward and forward + backward.

    Rollout: a scripted 4 s put_onto scene at 12 fps with the default substeps, for
    B = 1 and B = 64 scenes. Raster: 50 frames of hand + object + static at 240 x 427,
    and at half and quarter resolution. Prints a table and returns its rows.
    """

    device = torch.device(device)
    rows = []

    inputs, options = scripted_inputs(scripted_scene("put_onto"), 12.0, 4.0, dtype=torch.float32)
    steps = inputs.hand_vel.shape[1]
    for batch in (1, 64):
        tensors = inputs.map(lambda v: v.to(device).repeat(batch, *[1] * (v.ndim - 1)).requires_grad_())

        def forward():
            with torch.no_grad():
                return simulate(tensors, **options)

        def backward():
            out = simulate(tensors, **options)
            (out.object_pos.sum() + out.hand_pos.sum()).backward()

        for label, fn in (("forward", forward), ("forward+backward", backward)):
            first, median = timed(fn, repeats, device)
            rows.append(
                dict(kernel=f"rollout B={batch}", mode=label, first_s=first, median_s=median,
                     rate=f"{batch * steps / median:,.0f} steps/s")
            )

    truth = make_demonstration("put_onto", noise="none").truth
    f = lambda key: torch.as_tensor(truth[key], dtype=torch.float32, device=device)  # noqa: E731
    frames = np.linspace(0, len(truth["t"]) - 1, 50).round().astype(int)
    for scale in (1.0, 0.5, 0.25):
        scene = SceneTrajectories(
            hand_pos=f("hand_pos")[frames].requires_grad_(),
            hand_rot=f("hand_rot")[frames],
            object_pos=f("object_pos")[frames].requires_grad_(),
            object_rot=f("object_rot")[frames],
            object_size=f("object_size").requires_grad_(),
            static_pos=f("static_pos").requires_grad_(),
            static_rot=f("static_rot"),
            static_size=f("static_size"),
            camera_height=f("camera_height").requires_grad_(),
            camera_elevation=f("camera_elevation").requires_grad_(),
        )
        intrinsics = Intrinsics(truth["camera_K"], (240, 427)).scaled(scale)
        weights = torch.rand(50, 3, *intrinsics.image_size, device=device)
        pixels = 50 * intrinsics.image_size[0] * intrinsics.image_size[1]

        def forward():
            with torch.no_grad():
                return render_scene(scene, intrinsics, sigma=1.0)

        def backward():
            (render_scene(scene, intrinsics, sigma=1.0) * weights).sum().backward()

        for label, fn in (("forward", forward), ("forward+backward", backward)):
            first, median = timed(fn, repeats, device)
            size = "x".join(map(str, intrinsics.image_size))
            rows.append(
                dict(kernel=f"raster 50 x {size}", mode=label, first_s=first, median_s=median,
                     rate=f"{pixels / median / 1e6:,.1f} Mpx/s")
            )

    show(f"warpskill kernel benchmarks on {device} (median of {repeats}; first call includes compilation)")
    show(f"{'kernel':<24} {'mode':<17} {'first [s]':>10} {'median [ms]':>12}  rate")
    for r in rows:
        show(f"{r['kernel']:<24} {r['mode']:<17} {r['first_s']:>10.3f} {1e3 * r['median_s']:>12.2f}  {r['rate']}")
    return rows


