"""deltagen's Puma560 against independent libraries: roboticstoolbox-python (Corke's
``rtb.models.DH.Puma560()``) and pinocchio (a model built here from the DH table).

Both are in the ``test`` extra, so CI runs these tests; for users they are optional
(``pip install deltagen[bench]``), and every test here skips cleanly when its library is not
importable.

Conventions checked, and the one difference accounted for:

* rtb's DHRobot is standard DH, A_i = Rot_z(theta_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i),
  as deltagen's "standard"; its Puma560 has no joint offsets and identity base and tool.
* ``jacob0(q)`` is the geometric Jacobian of the tool point in the base frame, rows
  (vx, vy, vz, wx, wy, wz): deltagen's ``jacobian(q)`` (frame="base"); ``jacobe(q)`` is the
  same in the tool frame: ``jacobian(q, frame="tool")``.
* d1: rtb puts the shoulder 26.45 in = 0.67183 m above the mount; robots/puma560.toml may
  round it (0.6718 m). Since Trans_z(d1) commutes with Rot_z(q1),
  T_rtb(q) = Trans_z(d1_rtb - d1_deltagen) T_deltagen(q) exactly, and the base-frame
  Jacobian does not depend on d1 (both the tool point and every joint axis move alike).
  fk is compared with that shift; the tables are compared with d1 to within 0.05 mm.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltagen.api.serial import SerialRobot

TOL = 1e-12
COUNT = 1000
INCH = 0.0254
RTB_D1 = 26.45 * INCH  # rtb: "from mounting surface to shoulder axis"
D1_ROUNDING = 5e-5  # m; the file may give d1 to 0.1 mm

# Corke's Puma560 (standard DH), independent of both the robot file and rtb
PUMA_A = (0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0)
PUMA_D = (RTB_D1, 0.0, 0.15005, 0.4318, 0.0, 0.0)
PUMA_ALPHA = (math.pi / 2, 0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, 0.0)


@pytest.fixture(scope="module", params=["compiled", "reference"])
def puma(request):
    return SerialRobot.load("puma560", backend=request.param)


@pytest.fixture(scope="module")
def rtb_puma():
    rtb = pytest.importorskip("roboticstoolbox")
    return rtb.models.DH.Puma560()


@pytest.fixture(scope="module")
def configurations():
    """COUNT configurations: most within the joint limits, some anywhere in [-2 pi, 2 pi]."""
    robot = SerialRobot.load("puma560", backend="reference")
    rng = np.random.default_rng(560)
    lim = robot.qlim
    inside = rng.uniform(lim[:, 0], lim[:, 1], (COUNT - 200, 6))
    anywhere = rng.uniform(-2 * math.pi, 2 * math.pi, (200, 6))
    return np.ascontiguousarray(np.concatenate([inside, anywhere]))


def _shift(d1_from: float, d1_to: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = d1_to - d1_from
    return T


def _d1(robot) -> float:
    return robot.description.joints[0].d


# ------------------------------------------------------------------ roboticstoolbox-python


def test_dh_table_matches_rtb(rtb_puma):
    ours = SerialRobot.load("puma560").description
    assert ours.convention == "standard" and not rtb_puma.mdh
    assert ours.n == rtb_puma.n == 6
    np.testing.assert_array_equal(rtb_puma.base.A, np.eye(4))
    np.testing.assert_array_equal(rtb_puma.tool.A, np.eye(4))
    np.testing.assert_array_equal(ours.base, np.eye(4))
    np.testing.assert_array_equal(ours.tool, np.eye(4))
    for i, (j, link) in enumerate(zip(ours.joints, rtb_puma.links)):
        assert j.revolute and link.isrevolute, i
        assert abs(j.a - link.a) <= TOL, (i, j.a, link.a)
        assert abs(j.alpha - link.alpha) <= TOL, (i, j.alpha, link.alpha)
        assert abs(j.offset - link.offset) <= TOL, (i, j.offset, link.offset)
        np.testing.assert_allclose(j.qlim, link.qlim, rtol=0, atol=TOL, err_msg=f"qlim {i}")
        if i > 0:
            assert abs(j.d - link.d) <= TOL, (i, j.d, link.d)
    assert abs(rtb_puma.links[0].d - RTB_D1) <= TOL
    assert abs(ours.joints[0].d - RTB_D1) <= D1_ROUNDING, ours.joints[0].d


def test_fk_matches_rtb(puma, rtb_puma, configurations):
    T_rtb = np.array([T.A for T in rtb_puma.fkine(configurations)])
    T_ours = _shift(_d1(puma), rtb_puma.links[0].d) @ puma.fk(configurations)
    err = np.max(np.abs(T_ours - T_rtb))
    assert err <= TOL, f"max |T_deltagen - T_rtb| = {err:.3g}"


def test_fk_matches_rtb_cpp_ets(puma, rtb_puma, configurations):
    """rtb's C++ fast path (ETS.eval) too, on the same configurations."""
    T_rtb = rtb_puma.ets().eval(configurations)
    T_ours = _shift(_d1(puma), rtb_puma.links[0].d) @ puma.fk(configurations)
    assert np.max(np.abs(T_ours - T_rtb)) <= TOL


def test_jacob0_and_jacobe_match_rtb(puma, rtb_puma, configurations):
    J0 = np.array([rtb_puma.jacob0(q) for q in configurations])
    Je = np.array([rtb_puma.jacobe(q) for q in configurations])
    err0 = np.max(np.abs(puma.jacobian(configurations) - J0))
    erre = np.max(np.abs(puma.jacobian(configurations, frame="tool") - Je))
    assert err0 <= TOL, f"max |J_deltagen - jacob0| = {err0:.3g}"
    assert erre <= TOL, f"max |J_deltagen(tool) - jacobe| = {erre:.3g}"


@pytest.mark.parametrize("name", ["qz", "qr", "qs", "qn"])
def test_named_configurations_match_rtb(puma, rtb_puma, name):
    ours = puma.configuration(name)
    theirs = np.asarray(getattr(rtb_puma, name), dtype=float)
    np.testing.assert_array_equal(ours, theirs)
    T_ours = _shift(_d1(puma), rtb_puma.links[0].d) @ puma.fk(ours)
    assert np.max(np.abs(T_ours - rtb_puma.fkine(theirs).A)) <= TOL
    assert np.max(np.abs(puma.jacobian(ours) - rtb_puma.jacob0(theirs))) <= TOL


# ------------------------------------------------------------------ pinocchio


@pytest.fixture(scope="module")
def pin_puma():
    """(pinocchio module, model, data, tool frame id) of Corke's Puma560 (d1 = 26.45 in)."""
    pin = pytest.importorskip("pinocchio")
    model = pin.Model()
    parent, placement = 0, pin.SE3.Identity()
    for i, (a, d, alpha) in enumerate(zip(PUMA_A, PUMA_D, PUMA_ALPHA)):
        parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{i + 1}")
        # the fixed part of A_i after the joint's Rot_z: Trans_z(d) Trans_x(a) Rot_x(alpha)
        c, s = math.cos(alpha), math.sin(alpha)
        placement = pin.SE3(np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]]), np.array([a, 0, d]))
    fid = model.addFrame(pin.Frame("tool", parent, 0, placement, pin.FrameType.OP_FRAME))
    return pin, model, model.createData(), fid


def test_fk_and_jacobian_match_pinocchio(puma, pin_puma, configurations):
    pin, model, data, fid = pin_puma
    T_ours = _shift(_d1(puma), RTB_D1) @ puma.fk(configurations)
    J_ours = puma.jacobian(configurations)
    err_T = err_J = 0.0
    for q, T, J in zip(configurations, T_ours, J_ours):
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        err_T = max(err_T, np.max(np.abs(data.oMf[fid].homogeneous - T)))
        pin.computeJointJacobians(model, data, q)
        J_pin = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        err_J = max(err_J, np.max(np.abs(J_pin - J)))
    assert err_T <= TOL, f"max |T_deltagen - T_pinocchio| = {err_T:.3g}"
    assert err_J <= TOL, f"max |J_deltagen - J_pinocchio| = {err_J:.3g}"


def test_bench_pinocchio_model_is_the_robot(pin_puma, configurations):
    """deltagen.apps.bench.peers builds its pinocchio model from the robot's own description."""
    from deltagen.apps.bench.peers import pinocchio_model

    pin = pin_puma[0]
    robot = SerialRobot.load("puma560")
    model, fid = pinocchio_model(robot.description)
    data = model.createData()
    for q in configurations[:100]:
        pin.framesForwardKinematics(model, data, q)
        assert np.max(np.abs(data.oMf[fid].homogeneous - robot.fk(q))) <= TOL
