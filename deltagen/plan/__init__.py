"""Trajectories: time scaling, Cartesian paths, path following (``trajectory``).

May import: ``solve``, ``native``, ``reference``, and everything below them.
"""
