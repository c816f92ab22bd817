"""Serial chains, derived symbolically: ``chain`` (link transforms, fk,
Jacobians), ``ik_closed_form`` (closed-form inverse kinematics written as SymPy statements
with the arm's constants), ``ik_recipes`` (the closed forms' steps written once against a
small back end, no SymPy: ``ik_closed_form`` runs them as SymPy statements,
``solve.analytic`` on numpy arrays), ``dynamics`` (recursive Newton-Euler with the arm's
numbers), ``kernels`` (the batched kernels of one arm) and ``parts`` (which kernels each
part of a new arm's module holds; data only, read by the build without SymPy).
"""
