"""ik_all's completeness over the 6-joint chains of example-robot-data (legs and arms of
humanoids, mobile manipulators, the UR family) and random 6R arms: for random in-limit poses
with sigma_min / sigma_max of the Jacobian >= 1e-3, the original q is among the valid
solutions, every valid solution reproduces the pose to 1e-10 (the chain's own forward
kinematics, and pinocchio's for iCub's legs), the result says it is complete and no
IncompleteSolutionsWarning is raised. Which method serves each chain is pinned (the
structure detection reads the geometry: a chain moving to another method is a change to
look at). iCub's legs are a closed-form structure only up to the rounding of their file
(solve/nearest.py); an independent numeric multi-start finds no solution ik_all misses.

Run as a script for the longer table: ``python tests/solve/test_ik_completeness.py [POSES]``."""

from __future__ import annotations

import sys
import sysconfig
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from deltagen import IncompleteSolutionsWarning, SerialRobot
from deltagen.geometry.limits import fit_limits
from deltagen.model.urdf import URDFWarning
from deltagen.solve import numeric as ik_numeric
from deltagen.solve.nearest import NearestSolver, closed_form_solver, nearest_exact

ROBOTS_DIR = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"
POSES = 40  # per chain in the test run (the closing note's table: the script with 1000)

# name: (file, base link, tip link, the method ik_all uses)
CHAINS = {
    "ur3": ("ur_description/urdf/ur3_robot.urdf", "base_link", "tool0", "parallel_triple_6r"),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "base_link", "tool0", "parallel_triple_6r"),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", "base_link", "tool0", "parallel_triple_6r"),
    "kinova_j2s6s200": (
        "kinova_description/robots/kinova.urdf",
        "j2s6s200_link_base",
        "j2s6s200_end_effector",
        "spherical_wrist_6r",
    ),
    "anymal_kinova_arm": (
        "anymal_b_simple_description/robots/anymal-kinova.urdf",
        "j2s6s200_link_base",
        "j2s6s200_end_effector",
        "spherical_wrist_6r",
    ),
    "z1": ("z1_description/urdf/z1.urdf", "link00", "link06", "parallel_triple_6r"),
    "b1_z1_arm": ("b1_description/urdf/b1-z1.urdf", "link00", "link06", "parallel_triple_6r"),
    "centauro_arm": ("centauro_description/urdf/centauro.urdf", "torso_2", "arm1_6", "general6r"),
    "centauro_leg": (
        "centauro_description/urdf/centauro.urdf",
        "pelvis",
        "wheel_1",
        "parallel_triple_6r",
    ),
    "so100": ("so_arm_description/urdf/so100.urdf", "base", "jaw", "general6r"),
    "talos_right_leg": (
        "talos_data/robots/talos_full_v2.urdf",
        "base_link",
        "right_sole_link",
        "reversed_spherical_wrist_6r",
    ),
    "talos_left_leg": (
        "talos_data/robots/talos_reduced.urdf",
        "base_link",
        "left_sole_link",
        "reversed_spherical_wrist_6r",
    ),
    "icub_right_leg": (
        "icub_description/robots/icub.urdf",
        "root_link",
        "r_sole",
        "nearest_reversed_spherical_wrist_6r",
    ),
    "icub_left_leg": (
        "icub_description/robots/icub.urdf",
        "root_link",
        "l_sole",
        "nearest_reversed_spherical_wrist_6r",
    ),
    "romeo_right_leg": (
        "romeo_description/urdf/romeo.urdf",
        "body",
        "r_sole",
        "reversed_spherical_wrist_6r",
    ),
    "g1_left_leg": (
        "g1_description/urdf/g1_29dof_rev_1_0.urdf",
        "pelvis",
        "left_ankle_roll_link",
        "general6r",
    ),
    "alexander_left_leg": (
        "alexander_description/urdf/alexander_v1.lowerBodyOnly.urdf",
        "PELVIS_LINK",
        "LEFT_FOOT",
        "general6r",
    ),
    "human_left_leg": (
        "human_description/robots/human.urdf",
        "middle_pelvis",
        "left_foot",
        "reversed_spherical_wrist_6r",
    ),
    "simple_humanoid_right_leg": (
        "simple_humanoid_description/urdf/simple_humanoid.urdf",
        "BODY",
        "r_ankle",
        "reversed_spherical_wrist_6r",
    ),
}

needs_data = pytest.mark.skipif(
    not ROBOTS_DIR.is_dir(), reason="example-robot-data (test extra) is absent"
)


def _angle(a):
    return np.abs((a + np.pi) % (2 * np.pi) - np.pi)


def load(name: str, backend: str = "reference") -> SerialRobot:
    file, base, tip, _ = CHAINS[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        return SerialRobot.from_urdf(ROBOTS_DIR / file, base, tip, backend=backend)


def method_of(arm: SerialRobot) -> str:
    """The method ik_all(method="auto") uses: the closed form's structure, or general6r."""
    solver = closed_form_solver(arm.description)
    return "general6r" if solver is None else solver.structure


def well_conditioned(arm: SerialRobot, rng, count: int) -> np.ndarray:
    """``count`` random in-limit q (unbounded joints: +-pi) with sigma_min / sigma_max of
    the Jacobian >= 1e-3."""
    lim = np.array(arm.qlim, dtype=float)
    lim[~np.isfinite(lim)] = np.sign(lim[~np.isfinite(lim)]) * np.pi
    out = []
    while sum(len(x) for x in out) < count:
        q = rng.uniform(lim[:, 0], lim[:, 1], (4 * count, arm.n))
        s = np.linalg.svd(arm.jacobian(q), compute_uv=False)
        out.append(q[s[:, -1] / s[:, 0] >= 1e-3])
    return np.concatenate(out)[:count]


def completeness(arm: SerialRobot, q: np.ndarray, fk=None):
    """(complete flag, rows where the original q is found, largest fk error of the valid
    solutions) of ik_all for the poses of q; raises if an IncompleteSolutionsWarning is
    given."""
    T = arm.fk(q)
    with warnings.catch_warnings():
        warnings.simplefilter("error", IncompleteSolutionsWarning)
        result = arm.ik_all(T)
    Q, valid = result
    found = (valid & np.all(_angle(Q - q[:, None]) < 1e-8, axis=-1)).any(axis=1)
    rows, branches = np.nonzero(valid)
    err = np.abs((fk or arm.fk)(Q[rows, branches]) - T[rows]).max() if rows.size else 0.0
    assert np.all(arm.within_limits(Q[rows, branches]))
    return result.complete, found, float(err)


@needs_data
@pytest.mark.parametrize("name", sorted(CHAINS))
def test_every_chain_complete(name):
    arm = load(name)
    assert method_of(arm) == CHAINS[name][3]
    q = well_conditioned(arm, np.random.default_rng(sum(map(ord, name))), POSES)
    complete, found, err = completeness(arm, q)
    assert complete
    assert found.all(), f"{name}: original q missed on rows {np.flatnonzero(~found)[:10]}"
    assert err <= 1e-10


def test_random_6r_arms_complete():
    from helpers import random_6r_arm  # here: the file also runs as a script (__main__)

    rng = np.random.default_rng(7)
    for seed in range(3):
        arm = random_6r_arm(100 + seed, name=f"r6_{seed}")
        assert method_of(arm) == "general6r"
        complete, found, err = completeness(arm, well_conditioned(arm, rng, 30))
        assert complete and found.all() and err <= 1e-10


# -- iCub's legs: the nearest exact arm -----------------------------------------------


@needs_data
def test_icub_leg_is_nearly_a_reversed_central_wrist():
    """The file's iCub leg is Pieper's other case only up to its printed digits (pi/2 as
    1.5708): the nearest exact arm turns no axis by more than 1e-5 rad and moves none off its
    line, and its pose differs by some 1e-5 (m, and rad times the 1 m scale), which Newton
    removes."""
    arm = load("icub_right_leg")
    nearest = nearest_exact(arm.description)
    assert nearest is not None and nearest.inner.kind == "reversed"
    assert 1e-7 < nearest.moved_angle < 1e-5 and nearest.moved_length < 1e-5
    assert 1e-7 < nearest.deviation < 1e-4
    solver = closed_form_solver(arm.description)
    assert isinstance(solver, NearestSolver) and len(solver.configs) == 8


@needs_data
def test_icub_leg_no_solution_missed_by_a_multistart():
    """An independent numeric multi-start (64 random starts per pose, limits ignored, then
    wrapped into them): every solution it finds within the limits, away from singularities
    (sigma_min / sigma_max >= 1e-3), is one of ik_all's valid solutions."""
    arm = load("icub_right_leg")
    rng = np.random.default_rng(11)
    poses, seeds = 8, 64
    q = well_conditioned(arm, rng, poses)
    T = arm.fk(q)
    Q, valid = arm.ik_all(T)
    res = ik_numeric.solve(
        arm,
        np.repeat(T, seeds, axis=0),
        rng.uniform(-np.pi, np.pi, (poses * seeds, 6)),
        tol=1e-11,
        max_iter=200,
        restarts=0,
        respect_limits=False,
    )
    qn, inside = fit_limits(res.q, arm.qlim, [True] * 6)
    s = np.linalg.svd(arm.jacobian(np.nan_to_num(qn)), compute_uv=False)
    keep = res.converged & inside & (s[:, -1] / s[:, 0] >= 1e-3)
    assert keep.sum() > poses  # more than the original solutions
    rows = np.repeat(np.arange(poses), seeds)
    for r, qk in zip(rows[keep], qn[keep]):
        assert _angle(Q[r][valid[r]] - qk).max(-1).min() < 1e-7


@needs_data
def test_icub_leg_nearer_singularities():
    """Below the Newton-Kantorovich margin (solve/nearest.py) the coverage is measured, not
    proven: poses with sigma_min / sigma_max in [1e-4, 1e-3) (ten times nearer a singularity
    than the target asks) still give the original q among the valid solutions."""
    arm = load("icub_left_leg")
    lim = arm.qlim
    q = np.random.default_rng(13).uniform(lim[:, 0], lim[:, 1], (40000, 6))
    s = np.linalg.svd(arm.jacobian(q), compute_uv=False)
    ratio = s[:, -1] / s[:, 0]
    q = q[(ratio >= 1e-4) & (ratio < 1e-3)][:200]
    assert len(q) == 200
    complete, found, err = completeness(arm, q)
    assert complete and found.all() and err <= 1e-10


@needs_data
def test_icub_leg_as_pinocchio():
    """Every solution's pose by pinocchio reading the same file, and ik through the same
    solver. (The compiled backend runs the same numpy solver for such a chain: its C has no
    closed form, a build of some 45 s this file leaves out.)"""
    pytest.importorskip("pinocchio", reason="pinocchio (test extra) is not installed")
    arm = load("icub_right_leg")
    file, base, tip, _ = CHAINS["icub_right_leg"]
    from pinocchio_oracles import chain_pose_fk

    pin_fk = chain_pose_fk(ROBOTS_DIR / file, [j.name for j in arm.description.joints], base, tip)
    q = well_conditioned(arm, np.random.default_rng(12), 100)
    complete, found, err = completeness(arm, q, fk=pin_fk)
    assert complete and found.all() and err <= 1e-10
    q1 = arm.ik(arm.fk(q[:5]), q0=q[:5])  # ik: the branch nearest q0, from the same solver
    np.testing.assert_allclose(q1, q[:5], atol=1e-9)


def _leg(knee_tilt: float, yaw_offset: float) -> str:
    """A made-up leg (hip yaw, roll, pitch meeting; knee and ankle pitch parallel to the hip
    pitch; ankle roll), its knee axis tilted by ``knee_tilt`` rad and its hip yaw axis moved
    by ``yaw_offset`` m off the hip."""

    def joint(name, parent, child, xyz, axis, lim):
        return (
            f'<joint name="{name}" type="revolute"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>'
            f'<limit lower="{lim[0]}" upper="{lim[1]}"/></joint>'
        )

    return (
        '<?xml version="1.0"?><robot name="leg">'
        + "".join(f'<link name="{k}"/>' for k in ("pelvis", "l1", "l2", "l3", "l4", "l5", "l6"))
        + joint("hip_yaw", "pelvis", "l1", f"{yaw_offset} -0.08 -0.07", "0 0 1", (-0.8, 0.6))
        + joint("hip_roll", "l1", "l2", f"{-yaw_offset} 0 0", "1 0 0", (-0.5, 0.5))
        + joint("hip_pitch", "l2", "l3", "0 0 0", "0 1 0", (-2.0, 0.7))
        + joint(
            "knee",
            "l3",
            "l4",
            "0.01 0.02 -0.38",
            f"{np.sin(knee_tilt):.17g} {np.cos(knee_tilt):.17g} 0",
            (0.0, 2.6),
        )
        + joint("ankle_pitch", "l4", "l5", "-0.02 0.01 -0.36", "0 1 0", (-1.2, 0.7))
        + joint("ankle_roll", "l5", "l6", "0 0 0", "1 0 0", (-0.5, 0.5))
        + "</robot>"
    )


@pytest.mark.parametrize("tilt, offset", [(3e-6, 0.0), (2e-5, 4e-6)])
def test_nearly_special_leg_complete(tmp_path, tilt, offset):
    path = tmp_path / "leg.urdf"
    path.write_text(_leg(tilt, offset))
    arm = SerialRobot.from_urdf(path, backend="reference")
    assert method_of(arm) == "nearest_reversed_spherical_wrist_6r"
    complete, found, err = completeness(arm, well_conditioned(arm, np.random.default_rng(5), 200))
    assert complete and found.all() and err <= 1e-10


def test_a_real_offset_is_not_snapped(tmp_path):
    """A knee tilted by 1e-3 rad is the arm's geometry, not rounding: no nearest exact arm
    (the general solver answers, complete where its elimination is regular)."""
    path = tmp_path / "leg.urdf"
    path.write_text(_leg(1e-3, 0.0))
    arm = SerialRobot.from_urdf(path, backend="reference")
    assert nearest_exact(arm.description) is None
    assert method_of(arm) == "general6r"


def main(argv: list[str]) -> None:  # pragma: no cover - the closing note's table
    count = int(argv[0]) if argv else 1000
    print("| chain | method | complete | original q found / poses | max fk error | s |")
    print("|---|---|---|---|---|---|")
    for name in CHAINS:
        arm = load(name)
        q = well_conditioned(arm, np.random.default_rng(sum(map(ord, name)) + 1), count)
        t0 = time.perf_counter()
        complete, found, err = completeness(arm, q)
        dt = time.perf_counter() - t0
        print(
            f"| {name} | {method_of(arm)} | {complete} | {found.sum()}/{count} | {err:.1e} "
            f"| {dt:.1f} |",
            flush=True,
        )


if __name__ == "__main__":  # pragma: no cover
    main(sys.argv[1:])
