"""The rotary delta robot, derived symbolically (delta report eqs. (2)-(43)):
``symbols``, ``fk`` (direct kinematics), ``velocity``, ``acceleration``, ``ik`` (inverse
kinematics), ``printed`` (the equations as printed, for docs/errata.md) and ``kernels`` (the
batched kernels built from them).
"""
