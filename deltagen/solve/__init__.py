"""Inverse-kinematics solvers and singularity analysis of serial arms: ``analytic``
(closed form, numpy, built on the structure detected by ``model.structure``), ``numeric``
(damped Newton-Raphson), ``combined`` (explicit start + Newton), ``singularity``. Joint-limit
wrapping and the axis tests they share live in ``geometry`` (``limits``, ``axes``).

May import: ``native``, ``reference``, ``codegen``, ``derive``, ``model``, ``geometry``,
the foundation modules.
"""
