"""Trajectories: time scaling, Cartesian paths, path following (``trajectory``); path
following of six-axis arms through singular regions, with the lecture's remedies
(``singular_path``).

May import: ``solve``, ``native``, ``reference``, and everything below them.
"""
