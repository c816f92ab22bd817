"""URDF ``<mimic>`` joints as couplings (model/coupling.py, api/coupled.py): the reduced
chain in its independent variables against pinocchio's model of the same URDF with the
mimic joints free and the coupling expanded here by hand (q = E r + c written out from the
file's numbers, not from deltagen's Coupling)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import MIMIC

from deltagen import SerialRobot
from deltagen.api.coupled import CoupledArm
from deltagen.errors import GeometryError
from deltagen.inputs import InputError
from deltagen.model.urdf import chain_from_urdf, description_from_urdf

pin = pytest.importorskip("pinocchio", reason="pinocchio (test extra) is not installed")


E_HAND = np.array([[1, 0, 0], [0, 1, 0], [0, -0.5, 0], [0, -0.05, 0], [0, 0, 1]], dtype=float)
C_HAND = np.array([0, 0, 0.2, 0.1 * 0.2 + 0.01, 0])


@pytest.fixture(scope="module")
def mimic_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("mimic") / "mimic.urdf"
    path.write_text(MIMIC)
    return path


def test_reduced_chain_matches_pinocchio_with_the_mimic_expanded_by_hand(mimic_path):
    arm = SerialRobot.from_urdf(mimic_path, backend="reference")
    assert isinstance(arm, CoupledArm)
    assert arm.n == 3 and arm.joint_names == ("j1", "j2", "j5")
    model = pin.buildModelFromUrdf(str(mimic_path))  # mimic joints as free joints
    assert model.nq == 5
    data = model.createData()
    fid = model.getFrameId("l5")
    rng = np.random.default_rng(11)
    r, rd, rdd = (rng.uniform(-1.5, 1.5, (200, 3)) for _ in range(3))
    T, J, tau, M = arm.fk(r), arm.jacobian(r), arm.inverse_dynamics(r, rd, rdd), arm.mass_matrix(r)
    g = arm.gravity_torque(r)
    for k in range(len(r)):
        q = E_HAND @ r[k] + C_HAND
        pin.framesForwardKinematics(model, data, q)
        np.testing.assert_allclose(T[k], data.oMf[fid].homogeneous, atol=1e-12, rtol=0)
        Jp = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(J[k], Jp @ E_HAND, atol=1e-12, rtol=0)
        taup = pin.rnea(model, data, q, E_HAND @ rd[k], E_HAND @ rdd[k])
        np.testing.assert_allclose(tau[k], E_HAND.T @ taup, atol=1e-10, rtol=0)
        Mp = pin.crba(model, data, q)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        np.testing.assert_allclose(M[k], E_HAND.T @ Mp @ E_HAND, atol=1e-10, rtol=0)
        gp = pin.computeGeneralizedGravity(model, data, q)
        np.testing.assert_allclose(g[k], E_HAND.T @ gp, atol=1e-10, rtol=0)


def test_reduced_jacobian_dot_by_finite_differences(mimic_path):
    arm = SerialRobot.from_urdf(mimic_path, backend="reference")
    rng = np.random.default_rng(2)
    r, rd = rng.uniform(-1, 1, (20, 3)), rng.uniform(-1, 1, (20, 3))
    h = 1e-6
    fd = (arm.jacobian(r + h * rd) - arm.jacobian(r - h * rd)) / (2 * h)
    np.testing.assert_allclose(arm.jacobian_dot(r, rd), fd, atol=1e-7)


def test_coupled_arm_checks_and_nan_mode(mimic_path):
    arm = SerialRobot.from_urdf(mimic_path, backend="reference")
    with pytest.raises(
        InputError, match=r"\(\.\.\., 3\) for mimic_arm \(3 independent joints: j1, j2, j5\)"
    ):
        arm.fk(np.zeros(5))
    q = np.zeros((3, 3))
    q[1, 0] = np.nan
    T, valid = arm.fk(q, errors="nan")
    assert valid.tolist() == [True, False, True] and np.isnan(T[1]).all()
    J, valid = arm.jacobian(q, errors="nan")
    assert J.shape == (3, 6, 3) and valid.tolist() == [True, False, True]
    with pytest.raises(InputError, match=r"ik_all .* not available for a chain with coupled"):
        arm.ik_all(np.eye(4))
    # the coupled joints' own limits count: j3 = -0.5 q2 + 0.2 within [-3, 3]
    assert arm.within_limits([[0, 2.0, 0], [0, -6.0, 0]]).tolist() == [True, False]
    with pytest.raises(GeometryError, match="mimic others; read the chain with chain_from_urdf"):
        description_from_urdf(mimic_path)
    desc, coupling = chain_from_urdf(mimic_path)
    np.testing.assert_allclose(coupling.matrix, E_HAND)
    np.testing.assert_allclose(coupling.offset, C_HAND)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (('j2" multiplier', 'j9" multiplier'), r"names a joint that is not a movable joint"),
        (('<mimic joint="j2"', '<mimic joint="j3"'), r"a joint cannot mimic itself"),
        (('multiplier="-0.5"', 'multiplier="x"'), r"j3.*<mimic>"),
        (
            ('<axis xyz="0 1 0"/>', '<axis xyz="0 1 0"/><mimic joint="j3"/>'),
            r"mimic joints form a cycle",
        ),
    ],
)
def test_malformed_mimic(tmp_path, change, message):
    text = MIMIC.replace(*change)
    assert text != MIMIC
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(GeometryError, match=message):
        chain_from_urdf(path)


def test_bundled_ur5_urdf_loads_by_name():
    ur5 = SerialRobot.load("ur5", backend="reference")
    assert ur5.name == "ur5" and ur5.n == 6
    from deltagen.paths import robots_dir

    other = SerialRobot.from_urdf(robots_dir() / "ur5.urdf", backend="reference")
    q = np.random.default_rng(0).uniform(-3, 3, (10, 6))
    np.testing.assert_array_equal(ur5.fk(q), other.fk(q))
