"""The forward model of warpskill's Warp kernels, reimplemented in plain PyTorch (autograd).

Two uses: the oracle that the kernels' values and gradients are tested against
(``tests/test_reference.py``), and the "original approach" baseline of
``warpskill bench speed``.

- :func:`simulate_reference`: same arguments and output as :func:`warpskill.physics.simulate`.
- :func:`render_reference`: same arguments and output as :func:`warpskill.render.render_silhouettes`.
"""

from .physics import simulate_reference
from .raster import render_reference

__all__ = ["render_reference", "simulate_reference"]
