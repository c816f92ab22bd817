"""SymPy derivations: expressions only, no C text and no numerical solver.

``delta`` (``derive.delta``) holds the rotary delta robot of the delta report (fk,
velocity, acceleration, ik, dynamics, and the printed equations for the errata); ``serial``
(``derive.serial``) holds serial chains (the chain and its Jacobians, the closed-form IK
statements, dynamics); ``linear_delta`` (``derive.linear_delta``) the linear delta and
the tripod, whose direct kinematics reuse the delta's sphere intersection.``five_axis`` (``derive.five_axis``) the 5-axis NC machines' chain
and its closed-form inverse. ``kernel`` declares the
data a derivation hands on (a kernel's ports, stages and status); ``functions`` the few
SymPy functions beyond SymPy's own.

``hexapod`` (``derive.hexapod``) holds the hexapod's leg kinematics.

May import: ``model``, ``geometry``, the foundation modules.
"""
