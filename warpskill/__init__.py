"""warpskill: learn a manipulation skill from one video via approximate differentiable physics."""

__version__ = "0.1.0"
