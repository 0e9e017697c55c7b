"""The layers' import rules (docs/architecture.md): import-linter contracts and what they cannot say."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "warpskill"
LAYERS = ("contract", "data", "engine", "optimizer", "robot", "visual", "cluster", "bench")


def _imports_from(path: Path):
    """(module, name, line) of every ``from warpskill... import name`` in ``path``."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("warpskill"):
            for alias in node.names:
                yield node.module, alias.name, node.lineno


def test_import_contracts_hold():
    lint = shutil.which("lint-imports")
    if lint is None:
        pytest.skip("import-linter is not installed (pip install -e '.[test]')")
    result = subprocess.run([lint], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "BROKEN" not in result.stdout


def test_import_contracts_fail_on_a_broken_rule(tmp_path):
    """A contract-breaking import makes lint-imports fail (the check is not vacuous)."""
    lint = shutil.which("lint-imports")
    if lint is None:
        pytest.skip("import-linter is not installed")
    config = tmp_path / "contracts.toml"
    config.write_text(
        textwrap.dedent(
            """
            [tool.importlinter]
            root_packages = ["warpskill"]
            include_external_packages = true

            [[tool.importlinter.contracts]]
            name = "the optimiser imports no torch (false on purpose)"
            type = "forbidden"
            source_modules = ["warpskill.optimizer"]
            forbidden_modules = ["torch"]
            """
        )
    )
    result = subprocess.run([lint, "--config", str(config)], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode != 0
    assert "warpskill.optimizer" in result.stdout and "torch" in result.stdout


def test_no_underscored_name_is_imported_across_modules():
    offenders = [
        f"{path.relative_to(ROOT)}:{line}: {module}.{name}"
        for path in sorted(PACKAGE.rglob("*.py")) + sorted((ROOT / "kernels").glob("*.py"))
        for module, name, line in _imports_from(path)
        if name.startswith("_") or any(part.startswith("_") for part in module.split("."))
    ]
    assert not offenders, "\n".join(offenders)


def test_the_command_line_uses_public_names():
    """The CLI imports from the package or a layer's package, and only names in its ``__all__``.
    (The benchmarks time the stages themselves, so they may import any public module name; the
    underscore rule above holds for them too.)"""
    offenders = []
    for path in sorted((PACKAGE / "cli").glob("*.py")):
        for module, name, line in _imports_from(path):
            if module.startswith(("warpskill.cli", "warpskill.bench")):
                continue  # the command line's own modules, and the benchmark commands it runs
            public = getattr(importlib.import_module(module), "__all__", None)
            if module.count(".") > 1 and module != "warpskill.robot":
                offenders.append(f"{path.name}:{line}: {module} is not a layer's package")
            elif public is None or name not in public:
                offenders.append(f"{path.name}:{line}: {name} is not in {module}.__all__")
    assert not offenders, "\n".join(offenders)


def test_every_layer_declares_its_public_names():
    for layer in LAYERS:
        module = importlib.import_module(f"warpskill.{layer}")
        assert module.__doc__ and "import" in module.__doc__, f"warpskill.{layer} does not say what it may import"
        assert isinstance(module.__all__, (list, tuple)) and module.__all__, layer
        for name in module.__all__:  # a name, or a submodule (warpskill.bench's commands)
            assert hasattr(module, name) or importlib.util.find_spec(f"warpskill.{layer}.{name}"), f"{layer}.{name}"


def test_the_package_exports_every_public_name():
    import warpskill

    for name in warpskill.__all__:
        assert getattr(warpskill, name) is not None, name


def test_reading_data_and_judging_never_imports_torch_or_warp(tmp_path):
    """Loading a demonstration, judging a reconstruction, reading Something-Else boxes and
    estimating contact work in a process that has neither torch nor Warp loaded."""
    script = textwrap.dedent(
        f"""
        import json, sys
        import numpy as np
        import warpskill
        from warpskill import assets
        from warpskill.data import estimate_contact, read_something_else, something_else_demonstration

        videos = read_something_else(*(assets.path(f"examples/{{name}}") for name in
                                       ("annotations.json", "phases.csv", "actions.csv")))
        boxes_demo, _ = something_else_demonstration(next(iter(videos.values())))
        estimate_contact(boxes_demo.hand_mask, boxes_demo.object_mask)

        N, H, W = 6, 24, 32
        hand = np.zeros((N, H, W), np.uint8); hand[:, 2:8, 2:10] = 1
        obj = np.zeros((N, H, W), np.uint8); obj[:, 12:20, 12:22] = 1
        np.savez({str(tmp_path / "demo.npz")!r}, hand_mask=hand, object_mask=obj,
                 contact=np.array([0, 1, 1, 1, 0, 0], np.uint8), fps=np.array(12.0), action=np.array("pick_up"))
        demo = warpskill.Demonstration.load({str(tmp_path / "demo.npz")!r})
        contact = estimate_contact(demo.hand_mask, demo.object_mask)
        t = np.arange(N) / 12.0
        eye = np.broadcast_to(np.eye(3), (N, 3, 3))
        recon = warpskill.Reconstruction(
            fps=np.array(12.0), t=t, hand_pos=np.zeros((N, 3)) + [0, 0.5, 0.2], hand_rot=eye,
            grasp=np.zeros(N), grasped=np.zeros(N), object_pos=np.zeros((N, 3)) + [0, 0.5, 0.05],
            object_rot=eye, object_size=np.full(3, 0.1), static_pos=np.zeros((0, 3)),
            static_rot=np.zeros((0, 3, 3)), static_size=np.zeros((0, 3)), camera_K=np.eye(3),
            camera_elevation=np.array(0.5), camera_height=np.array(0.4), image_size=np.array([H, W]),
            action="pick_up", loss=np.array(0.0))
        warpskill.evaluate(recon, "pick_up")
        loaded = [m for m in ("torch", "warp") if m in sys.modules]
        print(json.dumps(loaded))
        """
    )
    result = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == "[]", result.stdout
