"""Trajectories, in three modules that import one way (``scaling`` <- ``cartesian`` <-
``following``): time scaling of a segment (``scaling``); Cartesian paths, orientation,
segments and ``PathBuilder`` (``cartesian``); inverse kinematics along a path, joint rates
and the lecture's path following (``following``). ``trajectory`` re-exports the three for
code written against the former single module. Path following of six-axis arms through
singular regions, with the lecture's remedies (``singular_path``).

May import: ``solve``, ``native``, ``reference``, and everything below them.
"""
