"""Inverse-kinematics solvers and singularity analysis of serial arms: ``analytic``
(closed form, numpy), ``numeric`` (damped Newton-Raphson), ``combined`` (explicit start +
Newton), ``singularity``.

May import: ``native``, ``reference``, ``codegen``, ``derive``, ``model``, ``geometry``,
the foundation modules.
"""
