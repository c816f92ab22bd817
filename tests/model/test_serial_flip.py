"""Reversed joints (``flip = true`` / ``sign = -1``, model/serial.py) in every convention.

Evidence:
* roboticstoolbox's Jaco DH model (its joint 1 is flipped): fk and the base-frame Jacobian of
  our description of the same rows, compiled and reference, against rtb's fkine / jacob0;
* the mirror identity: an arm with joint set S reversed at q equals the same arm unreversed
  at q' (q'_i = -q_i for i in S): fk(q) = fk'(q'), J(q) = J'(q') diag(s),
  Jdot(q, qd) = Jdot'(q', qd') diag(s), tau(q, qd, qdd) = diag(s) tau'(q', qd', qdd')
  (symmetric friction), checked on the compiled core (SymPy derivation) of standard DH,
  modified DH and universal-coordinate arms with a prismatic joint;
* pinocchio (apps.bench.peers.pinocchio_model, an about -z joint) on the flipped standard arm.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import rtb_dh_rows

from deltagen import SerialRobot
from deltagen.errors import GeometryError
from deltagen.model.serial import SerialDescription, transform

INERTIAL = dict(mass=1.5, com=[0.01, -0.02, 0.05], inertia=[0.02, 0.03, 0.025, 0.001, 0, 0.002])

DH_ROWS = [
    dict(a=0.1, alpha_deg=90, d=0.3, offset=0.2, viscous=0.5, coulomb=0.3, **INERTIAL),
    dict(a=0.4, alpha=0.1, d=0.05, **INERTIAL),
    dict(type="prismatic", a=0.05, alpha_deg=-90, theta=0.3, offset=0.1, **INERTIAL),
    dict(a=0.0, alpha_deg=90, d=0.25, offset=-0.4, **INERTIAL),
]
UC_ROWS = [
    dict(axis="z", tz=0.3, rx_deg=90, **INERTIAL),
    dict(axis="y", tx=0.4, ry=0.2, offset=0.3, **INERTIAL),
    dict(type="prismatic", axis="x", tx=0.1, rz_deg=-90, **INERTIAL),
    dict(axis="x", ty=0.2, tz=0.1, ry_deg=45, **INERTIAL),
]
FLIPPED = (0, 2, 3)


def _flipped(rows, how="flip"):
    out = []
    for i, row in enumerate(rows):
        row = dict(row)
        if i in FLIPPED:
            row.update({"flip": True} if how == "flip" else {"sign": -1})
        out.append(row)
    return out


def _desc(rows, convention, name):
    return SerialDescription.from_rows(
        rows,
        convention,
        name=name,
        base=transform([0.1, 0.0, 0.2], [0.1, 0.2, 0.3]),
        tool=transform([0.0, 0.02, 0.1], [0.3, 0.0, -0.2]),
    )


def _rel(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / max(1.0, np.max(np.abs(b))))


def _mirror(convention, backend, n=4):
    rows = (UC_ROWS if convention == "universal" else DH_ROWS)[:n]
    how = "sign" if convention == "modified" else "flip"
    flip = SerialRobot(
        _desc(_flipped(rows, how), convention, f"flip_{convention}{n}"), backend=backend
    )
    plain = SerialRobot(_desc(rows, convention, f"plain_{convention}"), backend="reference")
    s = np.array([-1.0 if i in FLIPPED else 1.0 for i in range(len(rows))])
    assert [j.sign for j in flip.description.joints] == s.tolist()
    rng = np.random.default_rng(3)
    q, qd, qdd = (rng.uniform(-2, 2, (300, n)) for _ in range(3))
    assert _rel(flip.fk(q), plain.fk(q * s)) < 1e-12
    assert _rel(flip.jacobian(q), plain.jacobian(q * s) * s) < 1e-12
    assert _rel(flip.jacobian_dot(q, qd), plain.jacobian_dot(q * s, qd * s) * s) < 1e-12
    tau = flip.inverse_dynamics(q, qd, qdd)
    assert _rel(tau, plain.inverse_dynamics(q * s, qd * s, qdd * s) * s) < 1e-10
    # the reference of the flipped arm agrees with its compiled core
    ref = flip.with_backend("reference")
    assert _rel(ref.jacobian(q), flip.jacobian(q)) < 1e-12
    assert _rel(ref.mass_matrix(q), flip.mass_matrix(q)) < 1e-10
    assert not np.allclose(flip.fk(q[:5]), plain.fk(q[:5]))  # the reversal matters


@pytest.mark.parametrize("convention", ["standard", "modified", "universal"])
def test_mirror_identity_reference(convention):
    _mirror(convention, "reference")


@pytest.mark.parametrize(
    "convention", ["standard", pytest.param("universal", marks=pytest.mark.slow)]
)
def test_mirror_identity_compiled_small(convention):
    """The SymPy derivation (chain and RNEA) of reversed joints, on a 3-joint arm with a
    prismatic joint (a small, quick build)."""
    _mirror(convention, "compiled", n=3)


@pytest.mark.slow
@pytest.mark.parametrize("convention", ["standard", "modified", "universal"])
def test_mirror_identity_compiled(convention):
    _mirror(convention, "compiled")


def test_flipped_standard_arm_against_pinocchio():
    pin = pytest.importorskip("pinocchio")
    from deltagen.apps.bench.peers import pinocchio_model

    desc = _desc(_flipped(DH_ROWS), "standard", "flip_pin")
    arm = SerialRobot(desc, backend="reference")
    model, fid = pinocchio_model(desc)
    data = model.createData()
    rng = np.random.default_rng(5)
    for q, qd, qdd in zip(*(rng.uniform(-2, 2, (50, 4)) for _ in range(3))):
        pin.framesForwardKinematics(model, data, q)
        T = data.oMf[fid].homogeneous
        assert _rel(arm.fk(q), T) < 1e-12
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        assert _rel(arm.jacobian(q), J) < 1e-12
        tau = pin.rnea(model, data, q, qd, qdd)
        friction = np.zeros(4)
        friction[0] = 0.5 * qd[0] + 0.3 * np.sign(qd[0])
        assert _rel(arm.inverse_dynamics(q, qd, qdd), tau + friction) < 1e-10


def test_jaco_against_roboticstoolbox():
    """rtb's Jaco reverses joint 1 (theta = -q1); our flipped row must agree."""
    rtb = pytest.importorskip("roboticstoolbox")
    jaco = rtb.models.DH.Jaco()
    assert jaco.links[0].isflip
    rows = rtb_dh_rows(jaco)
    rng = np.random.default_rng(7)
    q = rng.uniform(-np.pi, np.pi, (100, 6))
    T_rtb = np.array([jaco.fkine(x).A for x in q])
    J_rtb = np.array([jaco.jacob0(x) for x in q])
    arm = SerialRobot.from_dh(rows, "standard", name="jaco_rtb", backend="reference")
    assert _rel(arm.fk(q), T_rtb) < 1e-12
    assert _rel(arm.jacobian(q), J_rtb) < 1e-12
    unflipped = SerialRobot.from_dh(
        [{k: v for k, v in r.items() if k != "flip"} for r in rows],
        "standard",
        name="jaco_x",
        backend="reference",
    )
    assert _rel(unflipped.fk(q), T_rtb) > 1e-3  # the flip matters


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (dict(flip=1), "flip must be true or false"),
        (dict(sign=2), "sign must be 1 or -1"),
        (dict(sign=True), "sign must be 1 or -1"),
        (dict(flip=True, sign=-1), "flip or sign, not both"),
    ],
)
def test_bad_flip_keys(extra, message):
    with pytest.raises(GeometryError, match=message):
        SerialDescription.from_rows([dict(a=1.0, **extra)], "standard", name="bad_flip")


def test_flip_changes_the_fingerprint_only_when_set():
    plain = SerialDescription.from_rows([dict(a=1.0)], "standard", name="f")
    same = SerialDescription.from_rows([dict(a=1.0, flip=False)], "standard", name="f")
    flip = SerialDescription.from_rows([dict(a=1.0, sign=-1)], "standard", name="f")
    assert plain.key() == same.key() != flip.key()
