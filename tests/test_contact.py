"""Contact impulses and hand-tip distance: values against NumPy, adjoints against finite differences."""

import numpy as np
import pytest
import warp as wp
from device_support import warp_devices
from warpskill.kernels.contact import contact_impulses, hand_tip_distance
from warpskill.kernels.records import records, zeros

KP, KV, MU = 500.0, 5.0, 10.0

# the in-kernel accesses of these kernels are all read-only or write-only: any warning is an error
pytestmark = pytest.mark.filterwarnings("error:.*may corrupt gradient computation")


@pytest.fixture(autouse=True)
def _verify_array_access(verify_array_access):
    """Every test here runs with Warp's gradient-corrupting access checks on."""


# ---------------------------------------------------------------------------------------------
# NumPy reference (closest-point formulation, independent of the kernels' per-axis excesses)


def _unit_points() -> np.ndarray:
    grid = np.linspace(-0.5, 0.5, 5)
    faces = [(x, y, z) for z in (-0.5, 0.5) for y in grid for x in grid]
    edges = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.25, 0.0, 0.25)]
    return np.array(faces + edges)


def _box_distance(p: np.ndarray, half: np.ndarray, bottomless: bool) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance and outward normal of points p (P, 3) against a box in its frame."""
    low = np.array([-half[0], -half[1], -np.inf if bottomless else -half[2]])
    closest = np.clip(p, low, half)
    diff = p - closest
    dist = np.linalg.norm(diff, axis=1)
    top = p[:, 2] if bottomless else abs(p[:, 2])
    gaps = np.stack([half[0] - abs(p[:, 0]), half[1] - abs(p[:, 1]), half[2] - top], 1)
    axis = np.argmin(gaps, axis=1)
    rows = np.arange(len(p))
    inside_normal = np.zeros_like(p)
    inside_normal[rows, axis] = np.where(((axis == 2) & bottomless) | (p[rows, axis] >= 0), 1.0, -1.0)
    outside = dist > 0
    d = np.where(outside, dist, -gaps[rows, axis])
    n = np.where(outside[:, None], diff / np.maximum(dist, 1e-300)[:, None], inside_normal)
    return d, n


def _impulse(d: np.ndarray, n: np.ndarray, v: np.ndarray) -> np.ndarray:
    vn = (v * n).sum(1)
    m = np.maximum(-KP * d - KV * np.minimum(vn, 0.0), 0.0)
    return m[:, None] * n - (m > 0)[:, None] * MU * (v - vn[:, None] * n)


def _reference_impulses(s: dict, b: int) -> tuple[np.ndarray, np.ndarray]:
    q = (_unit_points() * s["object_size"][b]) @ s["object_rot"][b].T
    p = s["object_pos"][b] + q
    v = s["object_vel"][b] + np.cross(s["object_ang_vel"][b], q)
    j = _impulse(p[:, 2], np.tile([0.0, 0.0, 1.0], (len(p), 1)), v)
    for pos, rot, size in zip(s["static_pos"][b], s["static_rot"][b], s["static_size"][b]):
        d, n = _box_distance((p - pos) @ rot, size / 2, bottomless=True)
        j = j + _impulse(d, n @ rot.T, v)
    return j.sum(0), np.cross(q, j).sum(0)


# ---------------------------------------------------------------------------------------------
# scenes and launch helpers


def _rotation(rng, yaw_only=False) -> np.ndarray:
    if yaw_only:
        a = rng.uniform(-np.pi, np.pi)
        return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _scenes(seed: int, num_scenes: int = 6, num_statics: int = 2) -> dict:
    """Tilted cuboids touching the ground and static cuboids placed around them."""
    rng = np.random.default_rng(seed)
    size = rng.uniform(0.04, 0.15, (num_scenes, 3))
    static_size = rng.uniform(0.05, 0.15, (num_scenes, num_statics, 3))
    static_pos = np.concatenate(
        [rng.uniform(-0.08, 0.08, (num_scenes, num_statics, 2)), static_size[..., 2:] / 2], axis=2
    )
    return {
        "object_pos": np.c_[rng.uniform(-0.03, 0.03, (num_scenes, 2)), rng.uniform(0.0, 0.06, num_scenes)],
        "object_rot": np.stack([_rotation(rng) for _ in range(num_scenes)]),
        "object_vel": rng.normal(0.0, 0.3, (num_scenes, 3)),
        "object_ang_vel": rng.normal(0.0, 2.0, (num_scenes, 3)),
        "object_size": size,
        "static_pos": static_pos,
        "static_rot": np.array([[_rotation(rng, yaw_only=True) for _ in range(num_statics)] for _ in range(num_scenes)]),
        "static_size": static_size,
    }


def _arrays(s: dict, scalar, requires_grad=False, device="cpu") -> dict:
    vec3, mat33 = wp.types.vector(3, scalar), wp.types.matrix((3, 3), scalar)
    return {
        name: wp.array(value, dtype=mat33 if name.endswith("rot") else vec3, requires_grad=requires_grad,
                       device=device)
        for name, value in s.items()
    }


def _launch_impulses(a: dict, scalar, lanes: int = 1):
    """The impulses (B,) of the cuboids of ``a`` at their poses and velocities, through the kernels' records."""
    vec3 = wp.types.vector(3, scalar)
    Physics, Scene, _, Scratch = records(scalar)
    B, device = a["object_pos"].shape[0], a["object_pos"].device
    jv, jw = (wp.zeros(B, dtype=vec3, requires_grad=a["object_pos"].requires_grad, device=device) for _ in range(2))
    physics = Physics()
    physics.kp, physics.kv, physics.mu = KP, KV, MU
    scene = zeros(Scene, {name: (0,) * var.type.ndim for name, var in Scene.vars.items()}, device, False)
    for name in ("object_size", "static_pos", "static_rot", "static_size"):
        setattr(scene, name, a[name])
    scene.object_pos0, scene.object_rot0 = a["object_pos"], a["object_rot"]
    scratch = Scratch()  # state 0's velocities and impulses: (B, 1) views
    for name, array in (("own_vel", a["object_vel"]), ("own_ang_vel", a["object_ang_vel"]), ("impulse_v", jv),
                        ("impulse_w", jw)):
        setattr(scratch, name, array.reshape((B, 1)))
    contact_impulses(physics, scene, scratch, lanes)
    return jv, jw


def _check_adjoint_against_fd(s: dict, evaluate, seeds: list[np.ndarray], eps=1e-6, rtol=1e-6, device="cpu"):
    """Compare Warp's adjoint of sum(seed * output) with central differences, entry by entry, on ``device``."""
    a = _arrays(s, wp.float64, requires_grad=True, device=device)
    tape = wp.Tape()
    with tape:
        outputs = evaluate(a)
    tape.backward(grads={out: wp.array(seed, dtype=out.dtype, device=device) for out, seed in zip(outputs, seeds)})

    def loss(values: dict) -> float:
        outs = evaluate(_arrays(values, wp.float64, device=device))
        return sum(float((out.numpy() * seed).sum()) for out, seed in zip(outs, seeds))

    for name, value in s.items():
        adjoint = a[name].grad.numpy().reshape(value.shape)
        fd = np.zeros_like(value)
        for index in np.ndindex(value.shape):
            plus, minus = dict(s), dict(s)
            plus[name], minus[name] = value.copy(), value.copy()
            plus[name][index] += eps
            minus[name][index] -= eps
            fd[index] = (loss(plus) - loss(minus)) / (2 * eps)
        scale = np.abs(fd).max() + 1.0
        assert np.abs(adjoint - fd).max() <= rtol * scale, f"d/d{name}: adjoint {adjoint} vs FD {fd}"


# ---------------------------------------------------------------------------------------------
# tests


@pytest.mark.slow
@pytest.mark.parametrize("scalar, rtol", [(wp.float64, 1e-12), (wp.float32, 2e-5)])
@pytest.mark.parametrize("lanes", [1, 5], ids=["one thread", "5 threads"])
def test_impulses_match_numpy_reference(scalar, rtol, lanes):
    """One thread per cuboid adds all its sample points; 5 (not dividing 62) share them."""
    s = _scenes(seed=1)
    jv, jw = (out.numpy() for out in _launch_impulses(_arrays(s, scalar), scalar, lanes))
    for b in range(len(jv)):
        ref_v, ref_w = _reference_impulses(s, b)
        assert np.abs(ref_v).max() > 1.0, "scene without contact"
        # relative to the largest component of the scene's impulse
        assert np.allclose(jv[b], ref_v, rtol=0, atol=rtol * np.abs(ref_v).max())
        assert np.allclose(jw[b], ref_w, rtol=0, atol=rtol * np.abs(ref_w).max())


def test_resting_cuboid_is_pushed_by_its_bottom_grid_only():
    depth = 1e-3
    s = _scenes(seed=2, num_scenes=1, num_statics=0)
    s.update(object_pos=np.array([[0.1, 0.2, 0.05 - depth]]), object_rot=np.eye(3)[None], object_vel=np.zeros((1, 3)),
             object_ang_vel=np.zeros((1, 3)), object_size=np.array([[0.2, 0.1, 0.1]]))  # fmt: skip
    jv, jw = (out.numpy()[0] for out in _launch_impulses(_arrays(s, wp.float64), wp.float64))
    assert np.allclose(jv, [0.0, 0.0, 25 * KP * depth], rtol=1e-12, atol=1e-12)
    assert np.allclose(jw, 0.0, atol=1e-12)


def test_static_cuboid_bottom_does_not_push():
    """A cuboid deep inside a wide static cuboid, near its bottom, is pushed up by the top face."""
    depth = 0.085  # of the object's centre below the static's top face
    s = _scenes(seed=3, num_scenes=1, num_statics=1)
    s.update(static_pos=np.array([[[0.0, 0.0, 0.05]]]), static_rot=np.eye(3)[None, None],
             static_size=np.array([[[0.4, 0.4, 0.1]]]), object_rot=np.eye(3)[None],
             object_vel=np.zeros((1, 3)), object_ang_vel=np.zeros((1, 3)), object_size=np.array([[0.02, 0.02, 0.02]]),
             object_pos=np.array([[0.0, 0.0, 0.1 - depth]]))  # fmt: skip
    jv, jw = (out.numpy()[0] for out in _launch_impulses(_arrays(s, wp.float64), wp.float64))
    assert np.allclose(jv, [0.0, 0.0, 62 * KP * depth], rtol=1e-12, atol=1e-9)
    assert np.allclose(jw, 0.0, atol=1e-9)


@pytest.mark.parametrize("device", warp_devices())
@pytest.mark.parametrize("lanes", [1, 5], ids=["one thread", "5 threads"])
def test_impulse_adjoints_match_finite_differences(device, lanes):
    s = _scenes(seed=4, num_scenes=3, num_statics=2)
    rng = np.random.default_rng(0)
    seeds = [rng.normal(size=(3, 3)), rng.normal(size=(3, 3))]
    _check_adjoint_against_fd(s, lambda a: _launch_impulses(a, wp.float64, lanes), seeds, eps=1e-7, rtol=1e-6,
                              device=device)


def _launch_tip_distance(a: dict):
    d = wp.zeros(a["object_pos"].shape[0], dtype=wp.float64, requires_grad=a["object_pos"].requires_grad,
                 device=a["object_pos"].device)
    hand_tip_distance(a["object_size"], a["hand_pos"], a["object_pos"], a["object_rot"], d)
    return (d,)


def _tip_scene() -> dict:
    rng = np.random.default_rng(5)
    rot = np.stack([_rotation(rng) for _ in range(4)])
    size = np.array([[0.1, 0.08, 0.06]] * 4)
    # inside; outside a face; outside an edge; outside a corner (box frame)
    local = np.array([[0.02, -0.01, 0.015], [0.08, 0.01, -0.01], [0.07, 0.06, 0.005], [-0.07, 0.06, -0.05]])
    pos = rng.uniform(-0.1, 0.1, (4, 3))
    hand = pos + np.einsum("bij,bj->bi", rot, local)
    return {"hand_pos": hand, "object_pos": pos, "object_rot": rot, "object_size": size}


def test_tip_distance_matches_numpy_reference():
    s = _tip_scene()
    (d,) = _launch_tip_distance(_arrays(s, wp.float64))
    local = np.einsum("bji,bj->bi", s["object_rot"], s["hand_pos"] - s["object_pos"])
    ref = [_box_distance(p[None], size / 2, bottomless=False)[0][0] for p, size in zip(local, s["object_size"])]
    assert np.allclose(d.numpy(), ref, rtol=0, atol=1e-15)
    assert d.numpy()[0] < 0 < d.numpy()[1:].min()


@pytest.mark.parametrize("device", warp_devices())
def test_tip_distance_adjoints_match_finite_differences(device):
    s = _tip_scene()
    seeds = [np.random.default_rng(1).normal(size=4)]
    _check_adjoint_against_fd(s, _launch_tip_distance, seeds, eps=1e-7, rtol=1e-7, device=device)
