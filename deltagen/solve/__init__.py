"""Inverse-kinematics solvers and singularity analysis of serial arms: ``analytic``
(closed form, numpy, built on the structure detected by ``model.structure``), ``numeric``
(damped Newton-Raphson), ``combined`` (explicit start + Newton), ``general6r`` (every
solution of a general 6R arm, Raghavan-Roth elimination and an eigenvalue problem),
``singularity``, ``nearest`` (the closed form of a 6R chain's nearest exact arm, polished
by Newton on the chain: a structure up to the rounding of its file); ``ik`` (the IK planner
of a serial arm: which of those methods answers ``ik`` and ``ik_all``, built once per arm by
``SerialRobot``, and the result types ``IKSolutions`` / ``IKResult``); ``least_squares``
(the one damped least-squares core: the numeric solver, the calibration, the nearest-arm
polish and the path following of ``plan`` take their steps from it); and
``calibration`` (a built delta robot's per-chain geometry identified from measured pairs).
Joint-limit wrapping and the axis tests they share live in
``geometry`` (``limits``, ``axes``).

May import: ``native``, ``reference``, ``codegen``, ``derive``, ``model``, ``geometry``,
the foundation modules.
"""
