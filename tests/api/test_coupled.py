"""Inverse kinematics of coupled (URDF <mimic>) chains, api/coupled.py: numeric on the
independent variables. Evidence: round trips fk(ik(T)) = T on targets fk(r) of random r in
the box where every physical joint is within its limits, and the limits of the coupled
joints checked on the expanded q (within_limits of the full chain, its own code)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import MIMIC

from deltagen import SerialRobot
from deltagen.api.coupled import CoupledArm
from deltagen.errors import UnreachableError
from deltagen.inputs import InputError


def _joint(name, parent, child, xyz, axis, lim=(-2.8, 2.8), extra=""):
    return (
        f'<link name="{child}"/><joint name="{name}" type="revolute"><parent link="{parent}"/>'
        f'<child link="{child}"/><origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>'
        f'<limit lower="{lim[0]}" upper="{lim[1]}" effort="1" velocity="1"/>{extra}</joint>'
    )


# a 6-variable arm with a double elbow: elbow_b turns with the elbow, half as far and 0.1 rad
# ahead, within its own tighter limits [-0.8, 0.8] (so the elbow is held to [-1.8, 1.4])
DOUBLE_ELBOW = (
    '<?xml version="1.0"?>\n<robot name="double_elbow"><link name="base"/>'
    + _joint("shoulder_pan", "base", "l1", "0 0 0.3", "0 0 1")
    + _joint("shoulder_lift", "l1", "l2", "0 0.12 0.1", "0 1 0")
    + _joint("elbow", "l2", "l3", "0.05 -0.1 0.4", "0 1 0")
    + _joint(
        "elbow_b",
        "l3",
        "l4",
        "0 0 0.12",
        "0 1 0",
        (-0.8, 0.8),
        '<mimic joint="elbow" multiplier="0.5" offset="0.1"/>',
    )
    + _joint("wrist_1", "l4", "l5", "0 0 0.3", "0 1 0")
    + _joint("wrist_2", "l5", "l6", "0 0.09 0", "0 0 1")
    + _joint("wrist_3", "l6", "l7", "0 0 0.09", "0 1 0")
    + '<link name="tool"/><joint name="flange" type="fixed"><parent link="l7"/>'
    '<child link="tool"/><origin xyz="0 0.08 0.02" rpy="0.3 0 0"/></joint></robot>\n'
)


@pytest.fixture(scope="module")
def double_elbow(tmp_path_factory):
    path = tmp_path_factory.mktemp("coupled") / "double_elbow.urdf"
    path.write_text(DOUBLE_ELBOW)
    return CoupledArm.from_urdf(path, backend="reference")


def _random_r(arm, rng, count):
    box = arm.independent_limits()
    return rng.uniform(box[:, 0], box[:, 1], (count, arm.n))


def test_the_box_of_the_independent_variables_keeps_every_joint_within_limits(double_elbow):
    box = double_elbow.independent_limits()
    elbow = double_elbow.joint_names.index("elbow")
    np.testing.assert_allclose(box[elbow], [(-0.8 - 0.1) / 0.5, (0.8 - 0.1) / 0.5])
    rng = np.random.default_rng(1)
    assert double_elbow.within_limits(_random_r(double_elbow, rng, 500)).all()
    outside = np.zeros((2, 6))
    outside[:, elbow] = box[elbow] + [-1e-6, 1e-6]
    assert not double_elbow.within_limits(outside).any()


def test_ik_round_trip_of_a_coupled_6_variable_arm(double_elbow):
    rng = np.random.default_rng(2)
    r = _random_r(double_elbow, rng, 100)
    T = double_elbow.fk(r)
    r_ik = double_elbow.ik(T)
    assert r_ik.shape == r.shape
    np.testing.assert_allclose(double_elbow.fk(r_ik), T, rtol=0, atol=1e-10)
    assert double_elbow.within_limits(r_ik).all()
    # from a start near each answer the solver lands on it (no branch jump)
    r_near = double_elbow.ik(T, q0=r + 0.01)
    np.testing.assert_allclose(r_near, r, rtol=0, atol=1e-8)


def test_ik_of_the_mimic_of_a_mimic_chain(tmp_path):
    """3 independent variables of 5 joints (a prismatic one mimicking a revolute one that
    mimics another): a least-squares fit of all 6 components that is exact on fk(r)."""

    path = tmp_path / "mimic.urdf"
    path.write_text(MIMIC)
    arm = SerialRobot.from_urdf(path, backend="reference")
    assert isinstance(arm, CoupledArm) and arm.n == 3
    rng = np.random.default_rng(3)
    r = _random_r(arm, rng, 100)
    T = arm.fk(r)
    r_ik, ok = arm.ik(T, errors="nan")
    assert ok.all()
    np.testing.assert_allclose(arm.fk(r_ik), T, rtol=0, atol=1e-10)


def test_unreachable_targets_and_unsupported_requests_say_so(double_elbow):
    far = np.eye(4)
    far[:3, 3] = (3.0, 0.0, 0.3)
    r, ok = double_elbow.ik(np.stack([double_elbow.fk(np.zeros(6)), far]), errors="nan", restarts=3)
    assert ok.tolist() == [True, False] and np.isnan(r[1]).all()
    with pytest.raises(UnreachableError, match=r"no solution found in rows \[0\]"):
        double_elbow.ik(far, restarts=3)
    with pytest.raises(InputError, match=r"ik_all .*elbow_b mimic others"):
        double_elbow.ik_all(np.eye(4))
    with pytest.raises(InputError, match="closed-form inverse kinematics"):
        double_elbow.ik(np.eye(4), method="analytic")
    with pytest.raises(InputError, match=r"engine='c' is not available for a coupled chain"):
        double_elbow.ik(np.eye(4), engine="c")
    with pytest.raises(InputError, match=r"q0 must have shape \(\.\.\., 6\)"):
        double_elbow.ik(np.eye(4), q0=np.zeros(7))
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(InputError, match="not a rigid transform"):
        double_elbow.ik(bad)


def test_an_identity_coupling_hands_ik_to_the_full_chains_closed_form():
    from deltagen.paths import robots_dir

    arm = CoupledArm.from_urdf(robots_dir() / "scara_sr800.urdf", backend="reference")
    assert arm.is_free
    q = _random_r(arm, np.random.default_rng(4), 20)
    T = arm.fk(q)
    q_all, valid = arm.ik_all(T)
    assert valid.any(axis=1).all()
    for k in range(len(q)):
        np.testing.assert_allclose(
            arm.fk(q_all[k][valid[k]]), T[k][None].repeat(valid[k].sum(), 0), rtol=0, atol=1e-10
        )
    np.testing.assert_allclose(arm.fk(arm.ik(T)), T, rtol=0, atol=1e-10)
