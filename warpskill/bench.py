"""Benchmarks behind ``warpskill bench``: kernel microbenchmarks and the synthetic success table."""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch

from .actions import ACTIONS
from .camera import Intrinsics, world_to_camera


def timed(fn: Callable[[], object], repeats: int, device: torch.device) -> tuple[float, float]:
    """(first-call seconds, median seconds of ``repeats`` further calls) of ``fn``; the first call
    pays for compilation and caches, the median is the steady state (CUDA synchronised)."""

    def once() -> float:
        start = time.perf_counter()
        fn()
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        return time.perf_counter() - start

    first = once()
    return first, statistics.median(once() for _ in range(repeats))


def bench_kernels(device: str = "cpu", repeats: int = 5) -> list[dict]:
    """Time the physics rollout and the rasterizer, forward and forward + backward.

    Rollout: a scripted 4 s put_onto scene at 12 fps with the default substeps, for
    B = 1 and B = 64 scenes. Raster: 50 frames of hand + object + static at 240 x 427,
    and at half and quarter resolution. Prints a table and returns its rows.
    """
    from .initialize import SceneTrajectories, render_scene
    from .physics import simulate
    from .synthetic import make_demonstration, scripted_inputs, scripted_scene

    device = torch.device(device)
    rows = []

    inputs = scripted_inputs(scripted_scene("put_onto"), 12.0, 4.0, dtype=torch.float32)
    steps = inputs["hand_vel"].shape[1]
    for batch in (1, 64):
        tensors = {
            k: (v.to(device).repeat(batch, *[1] * (v.ndim - 1)).requires_grad_(v.is_floating_point()))
            if torch.is_tensor(v)
            else v
            for k, v in inputs.items()
        }

        def forward():
            with torch.no_grad():
                return simulate(**tensors)

        def backward():
            out = simulate(**tensors)
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

    print(f"warpskill kernel benchmarks on {device} (median of {repeats}; first call includes compilation)")
    print(f"{'kernel':<24} {'mode':<17} {'first [s]':>10} {'median [ms]':>12}  rate")
    for r in rows:
        print(f"{r['kernel']:<24} {r['mode']:<17} {r['first_s']:>10.3f} {1e3 * r['median_s']:>12.2f}  {r['rate']}")
    return rows


def camera_frame_errors(recon, truth: dict[str, np.ndarray]) -> dict[str, float]:
    """Median object-centre error [m] and object-size error [m] against the ground truth.

    Centres are compared in each scene's own camera frame, where the world's ambiguity
    (camera height and elevation) cancels; sizes as sorted edge lengths (a cuboid's axes
    may be permuted), mean absolute error.
    """

    def in_camera(pos, height, elevation):
        p = torch.as_tensor(np.asarray(pos, dtype=np.float64))
        return world_to_camera(p, torch.tensor(float(height), dtype=torch.float64),
                               torch.tensor(float(elevation), dtype=torch.float64)).numpy()

    est = in_camera(recon.object_pos, recon.camera_height, recon.camera_elevation)
    ref = in_camera(truth["object_pos"], truth["camera_height"], truth["camera_elevation"])
    size_error = np.abs(np.sort(recon.object_size) - np.sort(truth["object_size"])).mean()
    return {"centre": float(np.median(np.linalg.norm(est - ref, axis=1))), "size": float(size_error)}


def bench_synthetic(
    *,
    seeds: int = 3,
    noise: str = "moderate",
    actions: Sequence[str] | None = None,
    out: Path | None = None,
    device: str = "cpu",
    iterations: int | None = None,
) -> dict:
    """Reconstruct synthetic demonstrations of each action and print the paper's table.

    Rows: initialisation only, and the full method; columns: the actions (k/n), total, %.
    Also prints the median camera-frame object-centre and size errors and the time per
    demonstration.
    """
    from .evaluation import evaluate, success_table
    from .optimization import optimize
    from .synthetic import make_demonstration

    actions = list(actions or ACTIONS)
    rows: dict[str, list] = {"initialisation only": [], "full method": []}
    errors: dict[str, list] = {"initialisation only": [], "full method": []}
    seconds = []
    with tempfile.TemporaryDirectory() as scratch:
        for action in actions:
            for seed in range(seeds):
                demo = make_demonstration(action, seed=seed, noise=noise)
                folder = (out or Path(scratch)) / f"{action}_{seed}"
                folder.mkdir(parents=True, exist_ok=True)
                checkpoint = folder / "checkpoint.pt"
                start = time.perf_counter()
                for row, init_only in (("initialisation only", True), ("full method", False)):
                    recon = optimize(demo, device=device, iterations=iterations, seed=seed, progress=False,
                                     init_only=init_only, checkpoint=checkpoint)
                    ok = evaluate(recon, action).success
                    rows[row].append((action, ok))
                    errors[row].append(camera_frame_errors(recon, demo.truth))
                    if out is not None:
                        recon.save(folder / ("initialisation.npz" if init_only else "reconstruction.npz"))
                seconds.append(time.perf_counter() - start)
                if out is not None:
                    demo.save(folder / "demonstration.npz")
                print(f"{action:<22} seed {seed}: init {'ok  ' if rows['initialisation only'][-1][1] else 'fail'}"
                      f" full {'ok  ' if rows['full method'][-1][1] else 'fail'}  {seconds[-1]:6.1f} s", flush=True)

    print()
    print(success_table(rows))
    print()
    for row, errs in errors.items():
        centre = np.median([e["centre"] for e in errs])
        size = np.median([e["size"] for e in errs])
        print(f"{row:<20} median object-centre error {100 * centre:5.1f} cm, size error {100 * size:5.1f} cm")
    print(f"time per demonstration (both stages, {device}): median {statistics.median(seconds):.1f} s, "
          f"max {max(seconds):.1f} s")
    return {"rows": rows, "errors": errors, "seconds": seconds}
