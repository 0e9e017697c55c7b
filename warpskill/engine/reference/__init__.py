"""The forward model of warpskill's Warp kernels, reimplemented in plain PyTorch (autograd).

Two uses: the oracle that the kernels' values and gradients are tested against
(``tests/test_reference.py``), and the "original approach" baseline of
``warpskill bench speed``.

- :func:`simulate_reference`: same arguments and output as :func:`warpskill.engine.simulation.simulate`.
- :func:`render_reference`: same arguments and output as :func:`warpskill.engine.rendering.render_silhouettes`.
- :func:`simulate_dopri5`: the same model integrated as the paper does, adaptive dopri5
  (``torchdiffeq``) with grasp/release events and a hard switch; needs the ``baselines`` extra.
"""

from warpskill.engine.reference.physics import simulate_reference
from warpskill.engine.reference.raster import render_reference

try:
    from warpskill.engine.reference.dopri5 import simulate_dopri5
except ImportError:  # torchdiffeq (the optional extra "baselines") is missing
    simulate_dopri5 = None

__all__ = ["render_reference", "simulate_dopri5", "simulate_reference"]
