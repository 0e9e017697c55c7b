"""Everyday objects' typical sizes, looked up by the noun that names them.

A leaf below the optimiser (the noun prior), the data layer (the hand as a ruler) and the
benchmarks (size ratios): :mod:`~warpskill.nouns.table` holds the sizes and their sources,
:mod:`~warpskill.nouns.typical` the lookup and an adult hand's size. Imports NumPy only.
"""
