"""The rotary delta robot, derived symbolically (delta report eqs. (2)-(43)):
``symbols``, ``fk`` (direct kinematics), ``velocity``, ``acceleration``, ``ik`` (inverse
kinematics), ``inverse_rates`` (the inverse at velocity and acceleration level),
``dynamics`` (inverse dynamics by virtual work, exact and simplified), ``calibration`` (the
sensitivity of the platform position to each chain's parameters), ``printed`` (the
equations as printed, for docs/errata.md) and ``kernels`` (the batched kernels built from
them).
"""
