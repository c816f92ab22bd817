"""The numpy serial-arm reference (deltagen.reference.serial) against independent evidence:
the lecture's printed examples (slides 81-96), the EASY-ROB paper's universal coordinates
(eq. (3), table 1), hand-derived closed forms, the same arm written in three conventions,
and finite differences for every velocity quantity."""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltagen.inputs import InputError
from deltagen.model.serial import SerialDescription, transform
from deltagen.reference import serial as ref
from deltagen.status import INVALID, OK

DEG = math.pi / 180


# ------------------------------------------------------------------ independent helpers


def Rx(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def Ry(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def Rz(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def Tr(x=0.0, y=0.0, z=0.0):
    M = np.eye(4)
    M[:3, 3] = (x, y, z)
    return M


def vee(S):
    """Axial vector of the (near) skew part of (..., 3, 3)."""
    return 0.5 * np.stack(
        [S[..., 2, 1] - S[..., 1, 2], S[..., 0, 2] - S[..., 2, 0], S[..., 1, 0] - S[..., 0, 1]],
        axis=-1,
    )


def scara(L1=4.0, L2=3.0, **kw):
    return SerialDescription.from_rows(
        [dict(a=L1, alpha=0.0), dict(a=L2, alpha=0.0)], "standard", name="scara", **kw
    )


def random_arm(rng, convention, n=None, prismatic=0.3, frames=True):
    n = int(rng.integers(2, 7)) if n is None else n
    rows = []
    for _ in range(n):
        kind = "prismatic" if rng.random() < prismatic else "revolute"
        row = dict(type=kind, offset=rng.uniform(-1, 1))
        if convention == "universal":
            row.update(
                axis=str(rng.choice(["x", "y", "z"])),
                **{k: rng.uniform(-0.5, 0.5) for k in ("tx", "ty", "tz")},
                **{k: rng.uniform(-math.pi, math.pi) for k in ("rx", "ry", "rz")},
            )
        else:
            row.update(a=rng.uniform(-0.5, 0.5), alpha=rng.uniform(-math.pi, math.pi))
            if kind == "revolute":
                row["d"] = rng.uniform(-0.5, 0.5)
            else:
                row["theta"] = rng.uniform(-math.pi, math.pi)
        rows.append(row)
    kw = {}
    if frames:
        kw = dict(
            base=transform(rng.uniform(-1, 1, 3), rng.uniform(-3, 3, 3)),
            tool=transform(rng.uniform(-0.3, 0.3, 3), rng.uniform(-3, 3, 3)),
        )
    return SerialDescription.from_rows(rows, convention, **kw)


ARMS = [(c, k) for c in ("standard", "modified", "universal") for k in range(3)]


def fd_fk(desc, q, h=1e-5):
    """Central differences of fk: (N, 6, n) with [p_dot; vee(R_dot R^T)] per unit q_i."""
    N, n = q.shape
    T = ref.fk(desc, q)[0]
    J = np.empty((N, 6, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = h
        dT = (ref.fk(desc, q + e)[0] - ref.fk(desc, q - e)[0]) / (2 * h)
        J[:, :3, i] = dT[:, :3, 3]
        J[:, 3:, i] = vee(dT[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2))
    return J


# --------------------------------------------------------------- lecture: planar SCARA


def test_scara_numbers_slide95():
    """L1 = 4, L2 = 3, alpha = beta = 30 deg: x = 4.964, y = 4.598, psi = 60 deg."""
    T, st = ref.fk(scara(), np.array([[30 * DEG, 30 * DEG]]))
    assert st.tolist() == [OK]
    assert round(T[0, 0, 3], 3) == 4.964
    assert round(T[0, 1, 3], 3) == 4.598
    assert T[0, 2, 3] == pytest.approx(0.0, abs=1e-15)
    # the printed rotation block [0.5 -0.866 0; 0.866 0.5 0; 0 0 1] (3 decimals)
    np.testing.assert_allclose(
        T[0, :3, :3], [[0.5, -0.866, 0], [0.866, 0.5, 0], [0, 0, 1]], atol=5e-4
    )
    psi, theta, phi = ref.euler_zyx(T[0, :3, :3])
    assert psi == pytest.approx(60 * DEG, abs=1e-12)
    assert theta == pytest.approx(0.0, abs=1e-12)
    assert phi == pytest.approx(0.0, abs=1e-12)


def test_scara_links_and_closed_form_slides92_94(rng):
    """0T1, 1T2 as printed on slides 92/93 and 0T2 = [Rz(a+b) | L2 c(a+b) + L1 c(a), ...]."""
    L1, L2 = 0.7, 0.45
    q = rng.uniform(-math.pi, math.pi, (200, 2))
    a, b = q[:, 0], q[:, 1]
    A1, A2 = ref.link_transforms(scara(L1, L2), q)
    for A, ang, L in ((A1, a, L1), (A2, b, L2)):
        c, s = np.cos(ang), np.sin(ang)
        want = np.zeros((len(ang), 4, 4))
        want[:, 0] = np.stack([c, -s, 0 * c, L * c], 1)
        want[:, 1] = np.stack([s, c, 0 * c, L * s], 1)
        want[:, 2, 2] = want[:, 3, 3] = 1
        np.testing.assert_allclose(A, want, atol=1e-15)
    T, st = ref.fk(scara(L1, L2), q)
    assert np.all(st == OK)
    np.testing.assert_allclose(T[:, 0, 3], L1 * np.cos(a) + L2 * np.cos(a + b), atol=1e-14)
    np.testing.assert_allclose(T[:, 1, 3], L1 * np.sin(a) + L2 * np.sin(a + b), atol=1e-14)
    np.testing.assert_allclose(T[:, 2, 3], 0.0, atol=1e-15)
    np.testing.assert_allclose(T[:, :2, :2], np.array([Rz(x)[:2, :2] for x in a + b]), atol=1e-14)
    # orientation in the plane: psi = a + b (wrapped), theta = phi = 0
    ang = ref.euler_zyx(T[:, :3, :3])
    np.testing.assert_allclose(np.exp(1j * ang[:, 0]), np.exp(1j * (a + b)), atol=1e-13)
    np.testing.assert_allclose(ang[:, 1:], 0.0, atol=1e-13)
    # planar Jacobian in closed form
    J, _ = ref.jacobian(scara(L1, L2), q)
    s1, c1, s12, c12 = np.sin(a), np.cos(a), np.sin(a + b), np.cos(a + b)
    np.testing.assert_allclose(J[:, 0], np.stack([-L1 * s1 - L2 * s12, -L2 * s12], 1), atol=1e-14)
    np.testing.assert_allclose(J[:, 1], np.stack([L1 * c1 + L2 * c12, L2 * c12], 1), atol=1e-14)
    np.testing.assert_allclose(J[:, 2:5], 0.0, atol=1e-15)
    np.testing.assert_allclose(J[:, 5], 1.0, atol=1e-15)


def test_scara_printed_errata():
    """Slide 94's expanded product and slide 95's intermediate step as printed do not
    reproduce; the simplified forms and final numbers do (see the report)."""
    a = b = 30 * DEG
    L1, L2 = 4.0, 3.0
    T = ref.fk(scara(L1, L2), np.array([[a, b]]))[0][0]
    ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
    # printed a14 "cos a L2 cos b - sin a L2 sin b + L1 sin a" (should be + L1 cos a)
    printed_a14 = ca * L2 * cb - sa * L2 * sb + L1 * sa
    assert printed_a14 == pytest.approx(3.5)
    assert abs(printed_a14 - T[0, 3]) > 1.4
    assert ca * L2 * cb - sa * L2 * sb + L1 * ca == pytest.approx(T[0, 3], abs=1e-14)
    # printed a22 "-sin a cos b + cos a cos b" (should be -sin a sin b + cos a cos b)
    printed_a22 = -sa * cb + ca * cb
    assert abs(printed_a22 - T[1, 1]) > 0.1
    assert -sa * sb + ca * cb == pytest.approx(T[1, 1], abs=1e-14)
    # slide 95: a11 cos psi + a21 sin psi printed as 0.433 + 0.433; it is 0.25 + 0.75 = 1
    psi = math.atan2(T[1, 0], T[0, 0])
    assert T[0, 0] * math.cos(psi) == pytest.approx(0.25)
    assert T[1, 0] * math.sin(psi) == pytest.approx(0.75)


# ---------------------------------------------------------------- link matrices


def test_standard_link_matrix_slides81_82(rng):
    """The DH matrix of slide 81 / EASY-ROB eq. (2), revolute (theta = q + offset) and
    prismatic (d = q + offset, theta constant; slide 82)."""
    for kind in ("revolute", "prismatic"):
        a, alpha, d, th, off = rng.uniform(-2, 2, 5)
        row = dict(type=kind, a=a, alpha=alpha, offset=off)
        row.update(dict(d=d) if kind == "revolute" else dict(theta=th))
        desc = SerialDescription.from_rows([row], "standard")
        q = rng.uniform(-3, 3, (50, 1))
        (A,) = ref.link_transforms(desc, q)
        if kind == "revolute":
            t, dd = q[:, 0] + off, np.full(50, d)
        else:
            t, dd = np.full(50, th), q[:, 0] + off
        ct, st_, ca, sa = np.cos(t), np.sin(t), math.cos(alpha), math.sin(alpha)
        z = 0 * t
        want = np.stack(
            [
                np.stack([ct, -st_ * ca, st_ * sa, a * ct], 1),
                np.stack([st_, ct * ca, -ct * sa, a * st_], 1),
                np.stack([z, z + sa, z + ca, dd], 1),
                np.stack([z, z, z, z + 1], 1),
            ],
            1,
        )
        np.testing.assert_allclose(A, want, atol=1e-14)


def test_modified_link_matrix_craig(rng):
    """Craig's transform:
    [[ct, -st, 0, a], [st ca, ct ca, -sa, -sa d], [st sa, ct sa, ca, ca d]]."""
    for kind in ("revolute", "prismatic"):
        a, alpha, d, th, off = rng.uniform(-2, 2, 5)
        row = dict(type=kind, a=a, alpha=alpha, offset=off)
        row.update(dict(d=d) if kind == "revolute" else dict(theta=th))
        desc = SerialDescription.from_rows([row], "modified")
        q = rng.uniform(-3, 3, (50, 1))
        (A,) = ref.link_transforms(desc, q)
        if kind == "revolute":
            t, dd = q[:, 0] + off, np.full(50, d)
        else:
            t, dd = np.full(50, th), q[:, 0] + off
        ct, st_, ca, sa = np.cos(t), np.sin(t), math.cos(alpha), math.sin(alpha)
        z = 0 * t
        want = np.stack(
            [
                np.stack([ct, -st_, z, z + a], 1),
                np.stack([st_ * ca, ct * ca, z - sa, -sa * dd], 1),
                np.stack([st_ * sa, ct * sa, z + ca, ca * dd], 1),
                np.stack([z, z, z, z + 1], 1),
            ],
            1,
        )
        np.testing.assert_allclose(A, want, atol=1e-14)


def test_universal_link_matrix(rng):
    """D = Rot_axis(q + offset) Tx Ty Tz Rx Ry Rz, one joint at a time, against 4x4
    products of this test's own elementary matrices."""
    elem = {
        "x": (Rx, lambda v: Tr(x=v)),
        "y": (Ry, lambda v: Tr(y=v)),
        "z": (Rz, lambda v: Tr(z=v)),
    }
    for axis in "xyz":
        for kind in ("revolute", "prismatic"):
            p = dict(zip(("tx", "ty", "tz", "rx", "ry", "rz", "offset"), rng.uniform(-2, 2, 7)))
            desc = SerialDescription.from_rows([dict(type=kind, axis=axis, **p)], "universal")
            q = rng.uniform(-3, 3, (5, 1))
            (A,) = ref.link_transforms(desc, q)
            rot, tra = elem[axis]
            for k in range(5):
                v = q[k, 0] + p["offset"]
                motion = rot(v) if kind == "revolute" else tra(v)
                want = (
                    motion @ Tr(p["tx"], p["ty"], p["tz"]) @ Rx(p["rx"]) @ Ry(p["ry"]) @ Rz(p["rz"])
                )
                np.testing.assert_allclose(A[k], want, atol=1e-14)


# ------------------------------------------------------- lecture slide 96: P-R-P arm


def test_prp_arm_slide96(rng):
    """Joint 1 translation d1 along z, joint 2 rotation q2 about z, joint 3 translation d3
    horizontal. Printed solution: 0T3 = [[c2, -s2, 0, d3 c2], [s2, c2, 0, d3 s2],
    [0, 0, 1, d1], [0, 0, 0, 1]]."""
    q = np.column_stack(
        [rng.uniform(0, 2, 100), rng.uniform(-math.pi, math.pi, 100), rng.uniform(0, 1.5, 100)]
    )
    d1, q2, d3 = q.T
    c2, s2 = np.cos(q2), np.sin(q2)
    printed = np.zeros((100, 4, 4))
    printed[:, 0] = np.stack([c2, -s2, 0 * c2, d3 * c2], 1)
    printed[:, 1] = np.stack([s2, c2, 0 * c2, d3 * s2], 1)
    printed[:, 2] = np.stack([0 * c2, 0 * c2, 0 * c2 + 1, d1], 1)
    printed[:, 3, 3] = 1
    # universal coordinates reproduce the printed matrix as it stands
    uc = SerialDescription.from_rows(
        [
            dict(type="prismatic", axis="z"),
            dict(type="revolute", axis="z"),
            dict(type="prismatic", axis="x"),
        ],
        "universal",
    )
    T, st = ref.fk(uc, q)
    assert np.all(st == OK)
    np.testing.assert_allclose(T, printed, atol=1e-14)
    # standard DH: z2 must point along the slide's d3 direction (alpha2 = 90 deg, theta
    # offset 90 deg). DH's x3 is perpendicular to z2, so the printed frame 3 (x3 along the
    # d3 direction) is no DH frame: the tool transform Rx(-90) Rz(-90) turns it into it.
    dh = SerialDescription.from_rows(
        [dict(type="prismatic"), dict(alpha_deg=90, offset_deg=90), dict(type="prismatic")],
        "standard",
    )
    T, _ = ref.fk(dh, q)
    np.testing.assert_allclose(T[:, :3, 3], printed[:, :3, 3], atol=1e-14)
    dh_tool = SerialDescription.from_rows(
        [dict(type="prismatic"), dict(alpha_deg=90, offset_deg=90), dict(type="prismatic")],
        "standard",
        tool=Rx(-90 * DEG) @ Rz(-90 * DEG),
    )
    np.testing.assert_allclose(ref.fk(dh_tool, q)[0], printed, atol=1e-14)
    # the prismatic columns are the unit axis directions; the revolute one rotates about z
    J, _ = ref.jacobian(dh, q)
    np.testing.assert_allclose(J[:, :, 0], np.tile([0, 0, 1, 0, 0, 0.0], (100, 1)), atol=1e-14)
    np.testing.assert_allclose(J[:, :3, 2], np.stack([c2, s2, 0 * c2], 1), atol=1e-14)
    np.testing.assert_allclose(J[:, 3:, 2], 0.0, atol=0)
    np.testing.assert_allclose(
        J[:, :, 1], np.stack([-d3 * s2, d3 * c2, 0 * c2, 0 * c2, 0 * c2, 0 * c2 + 1], 1), atol=1e-14
    )


# --------------------------------------------------- one arm in three conventions


def three_conventions(base=None, tool=None):
    """A spatial 3R arm, hand-converted between the conventions.

    standard rows (a, alpha, d): (0, -90, 0.4), (0.5, 0, 0), (0.3, 45, 0.1), offsets o_i.
    modified (Craig): the a/alpha of row i move to row i+1, the last ones into the tool:
    (0, 0, 0.4), (0, -90, 0), (0.5, 0, 0.1), tool Trans_x(0.3) Rot_x(45 deg).
    universal: Rot_x(-90) Rot_z(q) = Rot_y(q) Rot_x(-90) and Rot_x(-90) (a, 0, d) = (a, d, 0)
    give D1 = Rot_z(q1) Trans_z(0.4); D2 = Rot_y(q2) Trans_x(0.5);
    D3 = Rot_y(q3) Trans(0.3, 0.1, 0) Rot_x(45 - 90 deg) -- the same frame 3 as standard DH.
    """
    base = np.eye(4) if base is None else base
    tool = np.eye(4) if tool is None else tool
    off = (0.2, -0.4, 0.7)
    std = SerialDescription.from_rows(
        [
            dict(a=0, alpha_deg=-90, d=0.4, offset=off[0]),
            dict(a=0.5, alpha=0, d=0, offset=off[1]),
            dict(a=0.3, alpha_deg=45, d=0.1, offset=off[2]),
        ],
        "standard",
        base=base,
        tool=tool,
    )
    mod = SerialDescription.from_rows(
        [
            dict(a=0, alpha=0, d=0.4, offset=off[0]),
            dict(a=0, alpha_deg=-90, d=0, offset=off[1]),
            dict(a=0.5, alpha=0, d=0.1, offset=off[2]),
        ],
        "modified",
        base=base,
        tool=Tr(x=0.3) @ Rx(45 * DEG) @ tool,
    )
    uni = SerialDescription.from_rows(
        [
            dict(axis="z", tz=0.4, offset=off[0]),
            dict(axis="y", tx=0.5, offset=off[1]),
            dict(axis="y", tx=0.3, ty=0.1, rx_deg=-45, offset=off[2]),
        ],
        "universal",
        base=base,
        tool=tool,
    )
    return std, mod, uni


def test_same_arm_three_conventions(rng):
    base = transform(rng.uniform(-1, 1, 3), rng.uniform(-3, 3, 3))
    tool = transform(rng.uniform(-0.2, 0.2, 3), rng.uniform(-3, 3, 3))
    q = rng.uniform(-math.pi, math.pi, (300, 3))
    poses = [ref.fk(d, q)[0] for d in three_conventions(base, tool)]
    np.testing.assert_allclose(poses[1], poses[0], atol=1e-14)
    np.testing.assert_allclose(poses[2], poses[0], atol=1e-14)
    # frames 1..3 of standard DH and universal coincide up to the constant rotations of the
    # derivation: F_std,1 = F_uni,1 Rot_x(-90 deg), F_std,2 = F_uni,2 Rot_x(-90 deg)
    std, mod, uni = three_conventions(base, tool)
    Fs, Fu = ref.frames(std, q)[0], ref.frames(uni, q)[0]
    np.testing.assert_allclose(Fs[:, 1], Fu[:, 1] @ Rx(-90 * DEG), atol=1e-14)
    np.testing.assert_allclose(Fs[:, 2], Fu[:, 2] @ Rx(-90 * DEG), atol=1e-14)
    np.testing.assert_allclose(Fs[:, 3], Fu[:, 3], atol=1e-14)
    # the physical joint axes are the same lines (direction and a common point)
    axes = [ref.joint_axes(d, q) for d in (std, mod, uni)]
    o0, w0 = axes[0]
    for o, w in axes[1:]:
        np.testing.assert_allclose(w, w0, atol=1e-14)
        np.testing.assert_allclose(np.cross(o - o0, w0), 0.0, atol=1e-14)
    # and the Jacobians (which depend only on those lines and the tool point) agree
    Js = [ref.jacobian(d, q)[0] for d in (std, mod, uni)]
    np.testing.assert_allclose(Js[1], Js[0], atol=1e-14)
    np.testing.assert_allclose(Js[2], Js[0], atol=1e-14)


def test_joint_axes_definitions(rng):
    """standard: z / origin of frame i-1; modified: of frame i; universal: `axis` of
    base D_1 .. D_{i-1}."""
    q = rng.uniform(-3, 3, (20, 5))
    for conv in ("standard", "modified"):
        desc = random_arm(rng, conv, n=5)
        F = ref.frames(desc, q)[0]
        o, w = ref.joint_axes(desc, q)
        k = np.arange(5) + (0 if conv == "standard" else 1)
        np.testing.assert_allclose(o, F[:, k][..., :3, 3], atol=1e-14)
        np.testing.assert_allclose(w, F[:, k][..., :3, 2], atol=1e-14)
    desc = random_arm(rng, "universal", n=5)
    F = ref.frames(desc, q)[0]
    o, w = ref.joint_axes(desc, q)
    for i, j in enumerate(desc.joints):
        np.testing.assert_allclose(o[:, i], F[:, i, :3, 3], atol=1e-14)
        np.testing.assert_allclose(w[:, i], F[:, i, :3, "xyz".index(j.axis)], atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(w, axis=-1), 1.0, atol=1e-14)


# ------------------------------------------------------ base, tool, offsets, prismatic


def test_base_tool_and_frames(rng):
    q = rng.uniform(-3, 3, (100, 2))
    # a base rotation about z adds to q1; a base translation shifts the point
    gamma = 0.8
    shifted = scara(4, 3, base=Tr(1, -2, 0.5) @ Rz(gamma))
    T = ref.fk(shifted, q)[0]
    T0 = ref.fk(scara(4, 3), q + [gamma, 0])[0]
    np.testing.assert_allclose(T[:, :3, :3], T0[:, :3, :3], atol=1e-14)
    np.testing.assert_allclose(T[:, :3, 3], T0[:, :3, 3] + [1, -2, 0.5], atol=1e-13)
    # a tool Trans_x(3) on an arm with a2 = 0 is the arm with a2 = 3
    np.testing.assert_allclose(
        ref.fk(scara(4, 0, tool=Tr(x=3)), q)[0], ref.fk(scara(4, 3), q)[0], atol=1e-14
    )
    # frames: F0 = base, F_{n+1} = F_n tool = fk
    desc = random_arm(rng, "universal", n=4)
    q = rng.uniform(-3, 3, (10, 4))
    F, st = ref.frames(desc, q)
    assert F.shape == (10, 6, 4, 4) and st.dtype == np.int8 and np.all(st == OK)
    np.testing.assert_allclose(F[:, 0], np.broadcast_to(desc.base, (10, 4, 4)), atol=0)
    np.testing.assert_allclose(F[:, 5], F[:, 4] @ desc.tool, atol=1e-14)
    np.testing.assert_allclose(ref.fk(desc, q)[0], F[:, 5], atol=0)
    As = ref.link_transforms(desc, q)
    M = np.broadcast_to(desc.base, (10, 4, 4))
    for i, A in enumerate(As):
        M = M @ A
        np.testing.assert_allclose(F[:, i + 1], M, atol=1e-14)
    # every frame is a rigid transform
    R = F[..., :3, :3]
    np.testing.assert_allclose(
        R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-13
    )
    np.testing.assert_allclose(F[..., 3, :], np.broadcast_to([0, 0, 0, 1.0], F.shape[:-1]), atol=0)


def test_joint_offsets(rng):
    q = rng.uniform(-3, 3, (50, 2))
    with_off = SerialDescription.from_rows(
        [dict(a=4, offset_deg=10), dict(a=3, offset=-0.3)], "standard"
    )
    np.testing.assert_allclose(
        ref.fk(with_off, q)[0], ref.fk(scara(), q + [10 * DEG, -0.3])[0], atol=1e-13
    )
    # prismatic offset adds to d; a prismatic joint with alpha = 0 lifts the point by d
    lift = SerialDescription.from_rows(
        [dict(a=4), dict(type="prismatic", offset=0.25, theta_deg=90)], "standard"
    )
    T = ref.fk(lift, q)[0]
    np.testing.assert_allclose(T[:, 2, 3], q[:, 1] + 0.25, atol=1e-14)
    np.testing.assert_allclose(T[:, 0, 3], 4 * np.cos(q[:, 0]), atol=1e-14)
    want = np.array([Rz(t + math.pi / 2)[:3, :3] for t in q[:, 0]])
    np.testing.assert_allclose(T[:, :3, :3], want, atol=1e-14)


# ------------------------------------------- EASY-ROB paper: MOTOMAN UP6, table 1, eq. (3)


def motoman():
    mm = 1e-3
    table = [
        (150, 0, 450, 0, 0, 0, "z"),
        (0, 0, 310, 0, 0, 0, "y"),
        (520, 0, 130, 0, 0, 0, "y"),
        (0, 0, 0, 0, 0, 0, "x"),
        (95, 0, 0, 0, 0, 0, "y"),
        (0, 0, 0, 0, 90, 0, "x"),
    ]
    rows = [
        dict(tx=tx * mm, ty=ty * mm, tz=tz * mm, rx_deg=rx, ry_deg=ry, rz_deg=rz, axis=ax)
        for tx, ty, tz, rx, ry, rz, ax in table
    ]
    return SerialDescription.from_rows(rows, "universal", name="up6")


def test_motoman_universal_coordinates(rng):
    arm = motoman()
    T, _ = ref.fk(arm, np.zeros((1, 6)))
    np.testing.assert_allclose(T[0], Tr(0.765, 0, 0.890) @ Ry(90 * DEG), atol=1e-15)
    # eq. (3) as a plain product of the paper's matrices at a random pose
    q = rng.uniform(-1, 1, 6)
    mm = 1e-3
    want = (
        Rz(q[0])
        @ Tr(150 * mm, 0, 450 * mm)
        @ Ry(q[1])
        @ Tr(0, 0, 310 * mm)
        @ Ry(q[2])
        @ Tr(520 * mm, 0, 130 * mm)
        @ Rx(q[3])
        @ Ry(q[4])
        @ Tr(95 * mm)
        @ Rx(q[5])
        @ Ry(90 * DEG)
    )
    np.testing.assert_allclose(ref.fk(arm, q[None])[0][0], want, atol=1e-15)
    # central wrist: with q5 = 0 the two x rotations add up
    qa = rng.uniform(-1, 1, (50, 6))
    qa[:, 4] = 0
    qb = qa.copy()
    qb[:, 3] += qb[:, 5]
    qb[:, 5] = 0
    np.testing.assert_allclose(ref.fk(arm, qa)[0], ref.fk(arm, qb)[0], atol=1e-14)
    # eq. (7): q1 = atan2(p_y, p_x) of the wrist point (origin of frame 3, on axes 4, 5, 6)
    qs = rng.uniform(-0.5, 0.5, (50, 6))
    F, _ = ref.frames(arm, qs)
    wrist = F[:, 3, :3, 3]
    np.testing.assert_allclose(np.arctan2(wrist[:, 1], wrist[:, 0]), qs[:, 0], atol=1e-14)
    o, w = ref.joint_axes(arm, qs)
    for i in (3, 4, 5):  # axes 4, 5, 6 pass through the wrist point
        np.testing.assert_allclose(np.cross(wrist - o[:, i], w[:, i]), 0.0, atol=1e-15)


# ------------------------------------------------------------------------- orientation


def test_euler_zyx_and_rpy(rng):
    ang = np.column_stack(
        [
            rng.uniform(-math.pi, math.pi, 200),
            rng.uniform(-1.5, 1.5, 200),
            rng.uniform(-math.pi, math.pi, 200),
        ]
    )
    R = np.array([(Rz(p) @ Ry(t) @ Rx(f))[:3, :3] for p, t, f in ang])
    np.testing.assert_allclose(ref.euler_zyx(R), ang, atol=1e-12)
    np.testing.assert_allclose(ref.rpy(R), ang[:, ::-1], atol=1e-12)
    # consistent with the description's transform(xyz, rpy)
    r = (0.3, -0.7, 2.5)
    np.testing.assert_allclose(ref.rpy(transform((0, 0, 0), r)[:3, :3]), r, atol=1e-14)
    # broadcasting over leading dimensions
    assert ref.euler_zyx(R.reshape(10, 20, 3, 3)).shape == (10, 20, 3)
    with pytest.raises(InputError):
        ref.euler_zyx(np.eye(4))


# ---------------------------------------------------------- velocities: finite differences


@pytest.mark.parametrize("conv,k", ARMS)
def test_jacobian_vs_finite_differences(conv, k, rng):
    desc = random_arm(rng, conv)
    q = rng.uniform(-3, 3, (40, desc.n))
    J, st = ref.jacobian(desc, q)
    assert J.shape == (40, 6, desc.n) and np.all(st == OK)
    np.testing.assert_allclose(J, fd_fk(desc, q), atol=2e-9)


@pytest.mark.parametrize("conv,k", ARMS)
def test_jacobian_tool_frame(conv, k, rng):
    """Tool frame: velocity R^T p_dot and angular velocity vee(R^T R_dot), by differences."""
    desc = random_arm(rng, conv)
    N, n, h = 30, desc.n, 1e-5
    q = rng.uniform(-3, 3, (N, n))
    Jt, st = ref.jacobian(desc, q, frame="tool")
    assert np.all(st == OK)
    T = ref.fk(desc, q)[0]
    Rt = np.swapaxes(T[:, :3, :3], 1, 2)
    for i in range(n):
        e = np.zeros(n)
        e[i] = h
        dT = (ref.fk(desc, q + e)[0] - ref.fk(desc, q - e)[0]) / (2 * h)
        v_tool = np.einsum("nij,nj->ni", Rt, dT[:, :3, 3])
        np.testing.assert_allclose(Jt[:, :3, i], v_tool, atol=2e-9)
        np.testing.assert_allclose(Jt[:, 3:, i], vee(Rt @ dT[:, :3, :3]), atol=2e-9)


@pytest.mark.parametrize("frame", ["base", "tool"])
@pytest.mark.parametrize("conv,k", ARMS)
def test_jacobian_dot_vs_finite_differences(conv, k, frame, rng):
    desc = random_arm(rng, conv)
    N, n, h = 40, desc.n, 1e-5
    q = rng.uniform(-3, 3, (N, n))
    qd = rng.uniform(-2, 2, (N, n))
    Jd, st = ref.jacobian_dot(desc, q, qd, frame=frame)
    assert Jd.shape == (N, 6, n) and np.all(st == OK)
    fd = (ref.jacobian(desc, q + h * qd, frame)[0] - ref.jacobian(desc, q - h * qd, frame)[0]) / (
        2 * h
    )
    np.testing.assert_allclose(Jd, fd, atol=5e-8)
    # zero joint rates: zero derivative; and linear in qd for a fixed q
    Jd0, _ = ref.jacobian_dot(desc, q, 0 * qd, frame=frame)
    np.testing.assert_allclose(Jd0, 0.0, atol=0)
    Jd2, _ = ref.jacobian_dot(desc, q, 2 * qd, frame=frame)
    np.testing.assert_allclose(Jd2, 2 * Jd, atol=1e-13)


def test_jacobian_dot_scara_closed_form(rng):
    """d/dt of the planar Jacobian: -L1 c1 qd1 - L2 c12 (qd1 + qd2) etc."""
    L1, L2 = 0.7, 0.45
    q = rng.uniform(-3, 3, (30, 2))
    qd = rng.uniform(-2, 2, (30, 2))
    Jd, _ = ref.jacobian_dot(scara(L1, L2), q, qd)
    a, ab = q[:, 0], q[:, 0] + q[:, 1]
    w1, w12 = qd[:, 0], qd[:, 0] + qd[:, 1]
    np.testing.assert_allclose(
        Jd[:, 0, 0], -L1 * np.cos(a) * w1 - L2 * np.cos(ab) * w12, atol=1e-14
    )
    np.testing.assert_allclose(Jd[:, 0, 1], -L2 * np.cos(ab) * w12, atol=1e-14)
    np.testing.assert_allclose(
        Jd[:, 1, 0], -L1 * np.sin(a) * w1 - L2 * np.sin(ab) * w12, atol=1e-14
    )
    np.testing.assert_allclose(Jd[:, 1, 1], -L2 * np.sin(ab) * w12, atol=1e-14)
    np.testing.assert_allclose(Jd[:, 2:], 0.0, atol=1e-15)


# ------------------------------------------------------------------ invalid input, shapes


def test_non_finite_rows_are_invalid(rng):
    desc = random_arm(rng, "modified", n=4)
    q = rng.uniform(-3, 3, (6, 4))
    qd = rng.uniform(-1, 1, (6, 4))
    q[1, 2] = np.nan
    q[3, 0] = np.inf
    qd[4, 1] = -np.inf
    bad_q = np.array([0, 1, 0, 1, 0, 0], bool)
    good = ~bad_q
    with np.errstate(all="raise"):  # no floating-point warnings from the bad rows
        T, st = ref.fk(desc, q)
        F, stf = ref.frames(desc, q)
        J, stj = ref.jacobian(desc, q)
        Jt, stt = ref.jacobian(desc, q, frame="tool")
        Jd, std = ref.jacobian_dot(desc, q, qd)
        o, w = ref.joint_axes(desc, q)
        As = ref.link_transforms(desc, q)
    for s in (st, stf, stj, stt):
        assert s.dtype == np.int8
        assert s.tolist() == [OK, INVALID, OK, INVALID, OK, OK]
    assert std.tolist() == [OK, INVALID, OK, INVALID, INVALID, OK]
    for X in (T, F, J, Jt, o, w, *As):
        assert np.all(np.isnan(X[bad_q]))
        assert np.all(np.isfinite(X[good]))
    assert np.all(np.isnan(Jd[std == INVALID])) and np.all(np.isfinite(Jd[std == OK]))
    # the valid rows are exactly what a clean batch gives
    np.testing.assert_array_equal(T[good], ref.fk(desc, q[good])[0])
    np.testing.assert_array_equal(J[good], ref.jacobian(desc, q[good])[0])


def test_empty_batch_and_shapes():
    desc = three_conventions()[0]
    q = np.zeros((0, 3))
    T, st = ref.fk(desc, q)
    assert T.shape == (0, 4, 4) and st.shape == (0,) and st.dtype == np.int8
    assert ref.frames(desc, q)[0].shape == (0, 5, 4, 4)
    assert ref.jacobian(desc, q)[0].shape == (0, 6, 3)
    assert ref.jacobian_dot(desc, q, q, frame="tool")[0].shape == (0, 6, 3)
    o, w = ref.joint_axes(desc, q)
    assert o.shape == w.shape == (0, 3, 3)
    assert [A.shape for A in ref.link_transforms(desc, q)] == [(0, 4, 4)] * 3
    for bad in (np.zeros(3), np.zeros((2, 4)), np.zeros((1, 2, 3)), [["a", "b", "c"]]):
        with pytest.raises(InputError):
            ref.fk(desc, bad)
    with pytest.raises(InputError):
        ref.jacobian(desc, np.zeros((1, 3)), frame="world")
    with pytest.raises(InputError):
        ref.jacobian_dot(desc, np.zeros((2, 3)), np.zeros((3, 3)))


def test_easyrob_eq9_is_not_the_law_of_cosines():
    """EASY-ROB paper eq. (9): q3 = pi - beta, beta = arccos(r / (l2z + l3z)). For a
    two-link arm l2 = 0.5, l3 = 0.3 bent by q3 = 60 deg, r = |shoulder-wrist| = 0.7: the
    printed formula gives 151 deg; the law of cosines gives back 60 deg (docs/errata.md)."""
    l2, l3, q3 = 0.5, 0.3, math.radians(60.0)
    desc = SerialDescription.from_rows([dict(a=l2), dict(a=l3)], "standard")
    T = ref.fk(desc, np.array([[0.0, q3]]))[0][0]
    r = math.hypot(T[0, 3], T[1, 3])
    assert r == pytest.approx(0.7, abs=1e-15)
    printed = math.pi - math.acos(r / (l2 + l3))
    assert math.degrees(printed) == pytest.approx(151.04, abs=0.01)
    law_of_cosines = math.pi - math.acos((l2**2 + l3**2 - r**2) / (2 * l2 * l3))
    assert law_of_cosines == pytest.approx(q3, abs=1e-12)
