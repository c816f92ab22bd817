"""The former single module of the trajectories, kept as a re-export so that code written
against ``deltagen.plan.trajectory`` (the import the README showed for ``PathBuilder``)
keeps working. The code lives in ``scaling`` (time scaling), ``cartesian`` (paths,
orientation, segments, ``PathBuilder``) and ``following`` (IK along a path, joint rates,
the lecture's path following); new code imports from those. The rotation helpers it used
to re-export (``as_rotation``, ``skew`` ... ``slerp``) are those of ``deltagen.geometry.rotations``.
"""

from __future__ import annotations

from deltagen.geometry.rotations import (
    as_rotation,
    matrix_from_quat,
    quat_from_matrix,
    quat_slerp,
    rot_exp,
    rot_log,
    skew,
    slerp,
)
from deltagen.plan.cartesian import (
    Arc,
    CartesianSamples,
    CartesianTrajectory,
    Line,
    PathBuilder,
    Segment,
)
from deltagen.plan.following import (
    JointTrajectory,
    PathFollowingTable,
    Task,
    TrajectoryError,
    exact_rates,
    jacobian_path_following,
    newton_step,
    numerical_rates,
    solve_ik,
    to_joint_trajectory,
)
from deltagen.plan.scaling import Quintic, Trapezoid

__all__ = [
    "Arc",
    "CartesianSamples",
    "CartesianTrajectory",
    "JointTrajectory",
    "Line",
    "PathBuilder",
    "PathFollowingTable",
    "Quintic",
    "Segment",
    "Task",
    "TrajectoryError",
    "Trapezoid",
    "as_rotation",
    "exact_rates",
    "jacobian_path_following",
    "matrix_from_quat",
    "newton_step",
    "numerical_rates",
    "quat_from_matrix",
    "quat_slerp",
    "rot_exp",
    "rot_log",
    "skew",
    "slerp",
    "solve_ik",
    "to_joint_trajectory",
]
