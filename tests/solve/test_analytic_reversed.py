"""ik_all of 6R chains whose first three axes meet in a point (a humanoid's hip: Pieper's
other case), solved backwards (model/structure.py ReversedChain, solve/analytic.py
ReversedSolver): the chain read from the foot has a central wrist and the closed form of the
Puma's class. Evidence: the original q among the valid solutions on every random in-limit
pose (sigma_min / sigma_max of the Jacobian >= 1e-3), every valid solution reproducing the
pose to 1e-10 with the chain's own forward kinematics (and pinocchio's for TALOS' legs); the
result's ``complete`` flag, and its warning where the method used is not complete."""

from __future__ import annotations

import sysconfig
import warnings
from pathlib import Path

import numpy as np
import pytest

from deltagen import IncompleteSolutionsWarning, SerialRobot
from deltagen.model.structure import ReversedChain, detect, reversed_description
from deltagen.model.urdf import URDFWarning

ROBOTS_DIR = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"
N = 1000


def _joint(name, parent, child, xyz, rpy, axis, lim):
    return (
        f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>'
        f'<limit lower="{lim[0]}" upper="{lim[1]}"/></joint>'
    )


# hip yaw, roll, pitch through one point (the hip), knee and ankle pitch parallel to the hip
# pitch, ankle roll; the pelvis offset, a thigh and shin with sideways offsets and a foot
# below the ankle, the base turned
LEG = (
    '<?xml version="1.0"?><robot name="leg">'
    + "".join(f'<link name="{k}"/>' for k in ("pelvis", "l1", "l2", "l3", "l4", "l5", "l6", "sole"))
    + _joint("hip_yaw", "pelvis", "l1", "0.02 -0.085 -0.07", "0.05 0 0.1", "0 0 1", (-0.8, 0.6))
    + _joint("hip_roll", "l1", "l2", "0 0 0", "0 0 0", "1 0 0", (-0.5, 0.5))
    + _joint("hip_pitch", "l2", "l3", "0 0 0", "0 0 0", "0 1 0", (-2.0, 0.7))
    + _joint("knee", "l3", "l4", "0.01 0.02 -0.38", "0 0 0", "0 1 0", (0.0, 2.6))
    + _joint("ankle_pitch", "l4", "l5", "-0.02 0.01 -0.36", "0 0 0", "0 1 0", (-1.2, 0.7))
    + _joint("ankle_roll", "l5", "l6", "0 0 0", "0 0 0", "1 0 0", (-0.5, 0.5))
    + '<joint name="sole_joint" type="fixed"><parent link="l6"/><child link="sole"/>'
    '<origin xyz="0.03 0 -0.1" rpy="0 0 0.2"/></joint></robot>'
)


def _angle(a):
    return np.abs((a + np.pi) % (2 * np.pi) - np.pi)


def _well_conditioned_poses(arm, rng, count=N):
    lim = arm.qlim
    q = rng.uniform(lim[:, 0], lim[:, 1], (3 * count, arm.n))
    s = np.linalg.svd(arm.jacobian(q), compute_uv=False)
    q = q[s[:, -1] / s[:, 0] >= 1e-3][:count]
    assert len(q) == count
    return q


def _assert_complete(arm, q, fk=None):
    T = arm.fk(q)
    result = arm.ik_all(T)
    assert result.complete
    Q, valid = result
    found = (valid & np.all(_angle(Q - q[:, None]) < 1e-8, axis=-1)).any(axis=1)
    assert found.all(), f"original q missed on rows {np.flatnonzero(~found)[:10]}"
    rows, branches = np.nonzero(valid)
    Tq = (fk or arm.fk)(Q[rows, branches])
    assert np.abs(Tq - T[rows]).max() <= 1e-10
    assert np.all(arm.within_limits(Q[rows, branches]))
    return valid


@pytest.fixture(scope="module")
def leg_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("leg") / "leg.urdf"
    path.write_text(LEG)
    return path


def test_the_reversed_chain_is_the_inverse(leg_path):
    arm = SerialRobot.from_urdf(leg_path, backend="reference")
    back = SerialRobot(reversed_description(arm.description), "reference")
    q = np.random.default_rng(1).uniform(-2, 2, (200, 6))
    np.testing.assert_allclose(back.fk(q[:, ::-1]), np.linalg.inv(arm.fk(q)), atol=1e-14)
    found = detect(arm.description)
    assert isinstance(found, ReversedChain) and found.inner.kind == "spherical_wrist_6r"
    np.testing.assert_array_equal(back.qlim, arm.qlim[::-1])


@pytest.mark.parametrize("backend", ["reference", "compiled"])
def test_leg_every_solution(leg_path, backend):
    arm = SerialRobot.from_urdf(leg_path, backend=backend)
    assert len(arm.analytic_configs()) == 8
    q = _well_conditioned_poses(arm, np.random.default_rng(2))
    valid = _assert_complete(arm, q)
    assert valid.sum(axis=1).max() >= 2  # more than the one branch found
    # one pose, and ik through the same closed form
    q1 = arm.ik(arm.fk(q[0]), q0=q[0])
    np.testing.assert_allclose(q1, q[0], atol=1e-9)
    # unreachable: no valid solution, and the answer is complete, so it means unreachable
    far = arm.fk(q[0])
    far[:3, 3] += [0.0, 0.0, -2.0]
    result = arm.ik_all(far)
    assert result.complete and not result.valid.any()


def test_compiled_backend_agrees_with_the_reference(leg_path):
    compiled = SerialRobot.from_urdf(leg_path)
    reference = compiled.with_backend("reference")
    q = _well_conditioned_poses(compiled, np.random.default_rng(3), 300)
    T = compiled.fk(q)
    Qc, vc = compiled.ik_all(T)
    Qr, vr = reference.ik_all(T)
    np.testing.assert_array_equal(vc, vr)
    assert _angle(Qc[vc] - Qr[vr]).max() <= 1e-8


def test_a_method_that_may_miss_solutions_says_so():
    arm = SerialRobot.load("puma560_offset_wrist", backend="reference")
    T = arm.fk(np.array([0.2, 0.4, -0.3, 0.5, 0.6, 0.1]))
    with pytest.warns(IncompleteSolutionsWarning, match="puma560_offset_wrist.*not complete"):
        result = arm.ik_all(T, method="combined")
    assert result.complete is False and result.valid.any()
    with warnings.catch_warnings():
        warnings.simplefilter("error", IncompleteSolutionsWarning)  # said once per method
        arm.ik_all(T, method="combined")
    puma = SerialRobot.load("puma560", backend="reference")
    assert puma.ik_all(T).complete


# TALOS' legs (base_link -> sole): hip yaw, roll, pitch meet; knee and ankle pitch parallel
TALOS_LEGS = {
    "right": ("talos_data/robots/talos_full_v2.urdf", "base_link", "right_sole_link"),
    "left": ("talos_data/robots/talos_full_v2.urdf", "base_link", "left_sole_link"),
}


@pytest.mark.skipif(not ROBOTS_DIR.is_dir(), reason="example-robot-data (test extra) is absent")
@pytest.mark.parametrize("side", sorted(TALOS_LEGS))
def test_talos_legs_every_solution_as_pinocchio(side):
    pytest.importorskip("pinocchio", reason="pinocchio (test extra) is not installed")
    file, base, tip = TALOS_LEGS[side]
    path = ROBOTS_DIR / file
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", URDFWarning)
        leg = SerialRobot.from_urdf(path, base, tip, backend="reference")
    assert detect(leg.description).kind == "reversed"
    # a pose that once failed: in limits, sigma_min / sigma_max 0.10
    if side == "right":
        q = np.array([-0.25, -0.12, -1.72, 1.89, -0.25, -0.2])
        Q, valid = leg.ik_all(leg.fk(q))
        assert np.any(valid & np.all(_angle(Q - q) < 1e-8, axis=-1))
    from pinocchio_oracles import chain_pose_fk

    pin_fk = chain_pose_fk(path, [j.name for j in leg.description.joints], base, tip)
    q = _well_conditioned_poses(leg, np.random.default_rng(4))
    _assert_complete(leg, q, fk=pin_fk)
