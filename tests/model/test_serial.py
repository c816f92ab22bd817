"""The bundled serial-arm robot files (robots/*.toml with a ``convention`` key).

Every such file must load, be named after its file stem, have sane joint limits and
configurations of the right length. For the files written from the sources, the test checks
the structure against the printed tables and reproduces printed numbers with its OWN 4x4
products (``_dh``, ``_uc`` and ``_fk`` below, plain numpy): deltagen's derivation, reference
and generated code are not used, so these are independent checks of the robot files.
The expected values are derived by hand in the comments next to each check.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from helpers import ROBOTS

from deltagen.model.serial import SerialDescription

DEG = math.pi / 180.0


def _serial_files() -> list[Path]:
    """robots/*.toml that describe serial arms (they state a convention; the delta robot
    file robots/default_delta.toml has none)."""
    files = []
    for path in sorted(ROBOTS.glob("*.toml")):
        with open(path, "rb") as fh:
            if "convention" in tomllib.load(fh):
                files.append(path)
    return files


SERIAL_FILES = _serial_files()

# stem -> (convention, joint types R/P base to tool)
EXPECTED = {
    "lecture_scara": ("standard", "RR"),  # slides 91-95: two revolute joints
    "lecture_prp": ("standard", "PRP"),  # slide 96: Translation, Rotation, Translation
    "manutec_h5": ("standard", "PRRR"),  # slide 97: d1 = Z, W2, W3, W4
    "bosch_sr800": ("standard", "RRPR"),  # slide 98: W1, W2, d3 = Z, W4
    "manutec_r15": ("standard", "RRRRRR"),  # slides 99/100: 3 main + 3 wrist axes
    "motoman_up6": ("universal", "RRRRRR"),  # EASY-ROB paper, table 1: A1..A6
    "miskolc_rrrr": ("standard", "RRRR"),  # Miskolc paper: "RRRR", n = 4
    "puma560": ("standard", "RRRRRR"),
}

# Configurations that are outside their limits as written but inside modulo 2 pi; each is
# documented in its file. Corke's Puma qn has q3 = pi, the range is [-225, 45] deg.
WRAPPED = set()


def _load(stem: str) -> SerialDescription:
    return SerialDescription.from_toml(ROBOTS / f"{stem}.toml")


# -- independent kinematics: plain 4x4 products ------------------------------------------


def _rot(axis: str, t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    T = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    T[i, i], T[i, j], T[j, i], T[j, j] = c, -s, s, c
    return T


def _trans(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _dh(a, alpha, d, theta) -> np.ndarray:
    """Standard DH (slides 81/82): Rot_z(theta) Trans_z(d) Trans_x(a) Rot_x(alpha)."""
    return _rot("z", theta) @ _trans(z=d) @ _trans(x=a) @ _rot("x", alpha)


def _mdh(a, alpha, d, theta) -> np.ndarray:
    """Modified DH (Craig): Rot_x(alpha) Trans_x(a) Rot_z(theta) Trans_z(d)."""
    return _rot("x", alpha) @ _trans(x=a) @ _rot("z", theta) @ _trans(z=d)


def _uc(j, q) -> np.ndarray:
    """Universal coordinates (EASY-ROB paper, eq. (3)): Rot_i(q_i) Tx Ty Tz Rx Ry Rz."""
    if j.revolute:
        motion = _rot(j.axis, q + j.offset)
    else:
        motion = _trans(**{j.axis: q + j.offset})
    return motion @ _trans(j.tx, j.ty, j.tz) @ _rot("x", j.rx) @ _rot("y", j.ry) @ _rot("z", j.rz)


def _fk(desc: SerialDescription, q) -> np.ndarray:
    """base . A_1(q_1) ... A_n(q_n) . tool; the joint variable enters as q + offset."""
    T = desc.base.copy()
    for j, qi in zip(desc.joints, q, strict=True):
        if desc.convention == "universal":
            A = _uc(j, qi)
        else:
            if j.revolute:
                d, theta = j.d, qi + j.offset
            else:
                d, theta = qi + j.offset, j.theta
            A = (_dh if desc.convention == "standard" else _mdh)(j.a, j.alpha, d, theta)
        T = T @ A
    return T @ desc.tool


def _random_q(desc: SerialDescription, rng, k=20) -> np.ndarray:
    lim = desc.qlim.copy()
    for i, j in enumerate(desc.joints):
        if not np.isfinite(lim[i]).all():
            lim[i] = (-math.pi, math.pi) if j.revolute else (0.0, 1.0)
    return rng.uniform(lim[:, 0], lim[:, 1], size=(k, desc.n))


# -- every serial robot file ---------------------------------------------------------------


def test_expected_files_are_bundled():
    stems = {p.stem for p in SERIAL_FILES}
    assert set(EXPECTED) <= stems
    assert "default_delta" not in stems


@pytest.mark.parametrize("path", SERIAL_FILES, ids=lambda p: p.stem)
def test_file_loads_and_is_named_after_its_stem(path):
    desc = SerialDescription.from_toml(path)
    assert desc.name == path.stem
    assert desc.name.isidentifier()
    assert desc.convention in ("standard", "modified", "universal")
    with open(path, "rb") as fh:
        raw = tomllib.load(fh)
    assert raw["convention"] == desc.convention  # stated explicitly, never defaulted
    assert len(desc.doc.strip()) > 40, "doc must name the source and the chosen values"
    names = [j.name for j in desc.joints if j.name]
    assert all(n.isidentifier() for n in names)
    assert len(set(names)) == len(names)


@pytest.mark.parametrize("path", SERIAL_FILES, ids=lambda p: p.stem)
def test_joint_limits_are_sane(path):
    desc = SerialDescription.from_toml(path)
    for i, j in enumerate(desc.joints):
        if j.qlim is None:
            continue
        lo, hi = j.qlim
        assert math.isfinite(lo) and math.isfinite(hi) and lo < hi, (i, j.qlim)
        if j.revolute:
            assert -2 * math.pi - 1e-9 <= lo and hi <= 2 * math.pi + 1e-9, (i, j.qlim)
        else:
            assert hi - lo <= 5.0, (i, j.qlim)  # metres: a stroke, not a unit slip


@pytest.mark.parametrize("path", SERIAL_FILES, ids=lambda p: p.stem)
def test_configurations_have_the_right_length_and_respect_limits(path):
    desc = SerialDescription.from_toml(path)
    lim = desc.qlim
    for key, q in desc.configurations.items():
        q = np.asarray(q, dtype=float)
        assert q.shape == (desc.n,) and np.all(np.isfinite(q)), key
        literal = bool(np.all((q >= lim[:, 0] - 1e-12) & (q <= lim[:, 1] + 1e-12)))
        if (desc.name, key) in WRAPPED:
            assert not literal, f"{desc.name}.{key} is listed as wrapped but is in range"
        else:
            assert literal, f"{desc.name}.{key} = {q} outside {lim.tolist()}"
        for i, j in enumerate(desc.joints):  # always inside modulo 2 pi
            if j.revolute:
                k = np.arange(-2, 3)
                assert np.any(
                    (q[i] + 2 * math.pi * k >= lim[i, 0] - 1e-12)
                    & (q[i] + 2 * math.pi * k <= lim[i, 1] + 1e-12)
                ), (key, i)
            else:
                assert lim[i, 0] - 1e-12 <= q[i] <= lim[i, 1] + 1e-12, (key, i)


@pytest.mark.parametrize("stem", sorted(EXPECTED))
def test_structure_matches_the_source(stem):
    desc = _load(stem)
    convention, types = EXPECTED[stem]
    assert desc.convention == convention
    assert "".join("R" if j.revolute else "P" for j in desc.joints) == types
    assert desc.n == len(types)


# -- lecture slides ---------------------------------------------------------------------------


def test_lecture_scara_table():
    desc = _load("lecture_scara")
    # slides 92/93: a1 = L1, a2 = L2, alpha = d = 0; slide 95: L1 = 4, L2 = 3
    assert [(j.a, j.alpha, j.d, j.offset) for j in desc.joints] == [(4, 0, 0, 0), (3, 0, 0, 0)]
    assert np.array_equal(desc.base, np.eye(4)) and np.array_equal(desc.tool, np.eye(4))


def test_lecture_scara_slide95_numbers():
    desc = _load("lecture_scara")
    q = desc.configurations["slide95"]
    assert np.allclose(q, [30 * DEG, 30 * DEG])
    T = _fk(desc, q)
    # x = 3 cos 60 + 4 cos 30 = 1.5 + 3.4641 = 4.9641, y = 3 sin 60 + 4 sin 30 = 4.5981;
    # the slide prints 4.964 and 4.598.
    assert T[0, 3] == pytest.approx(4.964, abs=5e-4)
    assert T[1, 3] == pytest.approx(4.598, abs=5e-4)
    assert T[2, 3] == pytest.approx(0.0, abs=1e-12)
    # printed rotation: [[0.5, -0.866], [0.866, 0.5]]
    assert np.allclose(T[:2, :2], [[0.5, -0.866], [0.866, 0.5]], atol=5e-4)
    # Euler angles after Vukobratovic (slide 89): psi = 60 deg, theta = phi = 0
    psi = math.atan2(T[1, 0], T[0, 0])
    assert math.degrees(psi) == pytest.approx(60.0, abs=1e-9)
    inner = T[0, 0] * math.cos(psi) + T[1, 0] * math.sin(psi)
    assert math.atan2(-T[2, 0], inner) == pytest.approx(0.0, abs=1e-12)
    assert math.atan2(T[2, 1], T[2, 2]) == pytest.approx(0.0, abs=1e-12)
    # Slide 95 evaluates the theta argument as "0,433 + 0,433"; it is
    # 0.5 cos 60 + 0.866 sin 60 = 0.25 + 0.75 = 1 (the print swapped cos psi and sin psi).
    # The angle, atan2(0, .) = 0, is unaffected.
    assert inner == pytest.approx(1.0, abs=1e-12)
    assert inner != pytest.approx(0.866, abs=1e-3)


def test_lecture_scara_slide94_product_and_its_erratum():
    desc = _load("lecture_scara")
    L1, L2 = 4.0, 3.0
    rng = np.random.default_rng(94)
    for a, b in rng.uniform(-math.pi, math.pi, size=(10, 2)):
        T = _fk(desc, (a, b))
        # simplified 0T2 of slide 94 (correct as printed)
        assert T[0, 3] == pytest.approx(L2 * math.cos(a + b) + L1 * math.cos(a), abs=1e-12)
        assert T[1, 3] == pytest.approx(L2 * math.sin(a + b) + L1 * math.sin(a), abs=1e-12)
        # expanded (2,4) entry as printed: sin a L2 cos b + cos a L2 sin b + L1 sin a (correct)
        assert T[1, 3] == pytest.approx(
            math.sin(a) * L2 * math.cos(b) + math.cos(a) * L2 * math.sin(b) + L1 * math.sin(a),
            abs=1e-12,
        )
    # Erratum: the expanded (1,4) entry is printed as
    #   cos a L2 cos b - sin a L2 sin b + L1 sin a;  it must end in L1 cos a.
    a = b = 30 * DEG
    printed = math.cos(a) * L2 * math.cos(b) - math.sin(a) * L2 * math.sin(b) + L1 * math.sin(a)
    corrected = math.cos(a) * L2 * math.cos(b) - math.sin(a) * L2 * math.sin(b) + L1 * math.cos(a)
    x = _fk(desc, (a, b))[0, 3]
    assert printed == pytest.approx(3.5)  # 1.5 + 2.0, not the slide-95 value 4.964
    assert x != pytest.approx(printed, abs=0.1)
    assert x == pytest.approx(corrected, abs=1e-12)
    # The extracted (2,2) entry reads "- sin a cos b + cos a cos b"; correct is
    # cos a cos b - sin a sin b = cos(a + b) (0.5 here; the extracted text gives 0.317).
    extracted_a22 = -math.sin(a) * math.cos(b) + math.cos(a) * math.cos(b)
    assert _fk(desc, (a, b))[1, 1] == pytest.approx(math.cos(a + b), abs=1e-12)
    assert extracted_a22 != pytest.approx(math.cos(a + b), abs=0.1)


def test_lecture_scara_slide111_start_point():
    desc = _load("lecture_scara")
    q = desc.configurations["slide111_start"]
    assert np.allclose(q, [10 * DEG, 30 * DEG])
    # x = 4 cos 10 + 3 cos 40 = 3.93923 + 2.29813 = 6.23736; y = 0.69459 + 1.92836 = 2.62295
    # (slide 111: "Startposition: x = 6,2374, y = 2,6230").
    T = _fk(desc, q)
    assert T[0, 3] == pytest.approx(6.2374, abs=5e-5)
    assert T[1, 3] == pytest.approx(2.6230, abs=5e-5)
    # slide 109: det J = L1 L2 sin q2 (= 6 sin 30 deg = 3 here), by central differences
    h = 1e-6
    J = np.column_stack(
        [
            (_fk(desc, np.add(q, dq))[:2, 3] - _fk(desc, np.subtract(q, dq))[:2, 3]) / (2 * h)
            for dq in (np.array([h, 0.0]), np.array([0.0, h]))
        ]
    )
    assert np.linalg.det(J) == pytest.approx(4 * 3 * math.sin(q[1]), rel=1e-6)


def test_lecture_prp_reproduces_printed_0T3():
    desc = _load("lecture_prp")
    # The tool rotation, built here independently: Rot_x(-90) Rot_z(-90) (= rpy [0, -90, -90]).
    assert np.allclose(desc.tool, _rot("x", -math.pi / 2) @ _rot("z", -math.pi / 2), atol=1e-12)
    rng = np.random.default_rng(96)
    for d1, q2, d3 in zip(
        rng.uniform(-1, 1, 20),
        rng.uniform(-math.pi, math.pi, 20),
        rng.uniform(0, 2, 20),
        strict=True,
    ):
        c, s = math.cos(q2), math.sin(q2)
        printed = np.array([[c, -s, 0, d3 * c], [s, c, 0, d3 * s], [0, 0, 1, d1], [0, 0, 0, 1]])
        assert np.allclose(_fk(desc, (d1, q2, d3)), printed, atol=1e-12)


def test_manutec_h5_table_and_pose():
    desc = _load("manutec_h5")
    L1, L2, T_len = 0.40, 0.30, 0.10
    rows = [(j.a, j.alpha, j.d, j.theta, j.offset) for j in desc.joints]
    # slide 97: (0, 0, Z, 0), (L1, 0, 0, W2), (L2, 0, 0, W3), (0, 0, -T, W4)
    assert rows == [(0, 0, 0, 0, 0), (L1, 0, 0, 0, 0), (L2, 0, 0, 0, 0), (0, 0, -T_len, 0, 0)]
    # home: stretched along x0 at lift Z = 0.35: tool point (L1 + L2, 0, Z - T) = (0.70, 0, 0.25)
    assert np.allclose(_fk(desc, desc.configurations["home"])[:3, 3], [0.70, 0.0, 0.25])
    for Z, w2, w3, w4 in _random_q(desc, np.random.default_rng(97)):
        T = _fk(desc, (Z, w2, w3, w4))
        assert np.allclose(
            T[:3, 3],
            [
                L1 * math.cos(w2) + L2 * math.cos(w2 + w3),
                L1 * math.sin(w2) + L2 * math.sin(w2 + w3),
                Z - T_len,
            ],
        )
        assert np.allclose(T, _trans(*T[:3, 3]) @ _rot("z", w2 + w3 + w4), atol=1e-12)


def test_bosch_sr800_table_and_pose():
    desc = _load("bosch_sr800")
    L1, L2, H = 0.45, 0.35, 0.50
    rows = [(j.a, j.alpha, j.d, j.theta, j.offset) for j in desc.joints]
    # slide 98: (L1, 0, H, W1), (L2, 180 deg, 0, W2), (0, 0, Z, 0), (0, 0, 0, W4)
    assert rows == [(L1, 0, H, 0, 0), (L2, math.pi, 0, 0, 0), (0, 0, 0, 0, 0), (0, 0, 0, 0, 0)]
    assert L1 + L2 == pytest.approx(0.80)  # reach from the type number SR 800
    # q = 0: flange at (L1 + L2, 0, H) = (0.80, 0, 0.50), z axis down (alpha2 = 180 deg)
    T0 = _fk(desc, desc.configurations["qz"])
    assert np.allclose(T0[:3, 3], [0.80, 0.0, 0.50]) and np.allclose(T0[:3, 2], [0, 0, -1])
    for w1, w2, Z, w4 in _random_q(desc, np.random.default_rng(98)):
        T = _fk(desc, (w1, w2, Z, w4))
        # Z positive moves down ("Wunschrichtung fuer Achse 3")
        assert np.allclose(
            T[:3, 3],
            [
                L1 * math.cos(w1) + L2 * math.cos(w1 + w2),
                L1 * math.sin(w1) + L2 * math.sin(w1 + w2),
                H - Z,
            ],
        )
        assert np.allclose(T[:3, 2], [0, 0, -1])


def test_manutec_r15_table_and_poses():
    desc = _load("manutec_r15")
    H, L1, L2, L3 = 0.75, 0.65, 0.70, 0.15
    rows = [(j.a, j.alpha, j.d, j.offset) for j in desc.joints]
    # slide 100: alpha = -90, 0, -90, +90, -90, 0 deg; d = H, 0, 0, L2, 0, L3; a2 = L1;
    # theta3 = W3 - 90 deg
    r = math.pi / 2
    assert rows == [
        (0, -r, H, 0),
        (L1, 0, 0, 0),
        (0, -r, 0, -r),
        (0, r, L2, 0),
        (0, -r, 0, 0),
        (0, 0, L3, 0),
    ]
    # qz: stretched horizontally along x0: flange (L1 + L2 + L3, 0, H) = (1.50, 0, 0.75),
    # approach +x0
    T = _fk(desc, desc.configurations["qz"])
    assert np.allclose(T[:3, 3], [1.50, 0.0, 0.75]) and np.allclose(T[:3, 2], [1, 0, 0])
    # ready (W2 = -90, W3 = +90): upper arm up, forearm forward: (L2 + L3, 0, H + L1)
    T = _fk(desc, desc.configurations["ready"])
    assert np.allclose(T[:3, 3], [0.85, 0.0, 1.40]) and np.allclose(T[:3, 2], [1, 0, 0])
    # central wrist (slide 99: main axes 1-3, wrist axes 4-6): the wrist centre p - L3 a
    # depends on W1..W3 only
    rng = np.random.default_rng(100)
    for q in _random_q(desc, rng, k=10):
        q2 = q.copy()
        q2[3:] = rng.uniform(-1, 1, 3)
        c1 = _fk(desc, q)[:3, 3] - L3 * _fk(desc, q)[:3, 2]
        c2 = _fk(desc, q2)[:3, 3] - L3 * _fk(desc, q2)[:3, 2]
        assert np.allclose(c1, c2, atol=1e-12)


# -- EASY-ROB paper: MOTOMAN UP6 --------------------------------------------------------------


def test_motoman_up6_table():
    desc = _load("motoman_up6")
    # Table 1 (mm) and Rot_i = Rz1, Ry2, Ry3, Rx4, Ry5, Rx6
    table_mm = [
        (150, 0, 450, 0, 0, 0),
        (0, 0, 310, 0, 0, 0),
        (520, 0, 130, 0, 0, 0),
        (0, 0, 0, 0, 0, 0),
        (95, 0, 0, 0, 0, 0),
        (0, 0, 0, 0, 90, 0),
    ]
    for j, (tx, ty, tz, rx, ry, rz), axis in zip(desc.joints, table_mm, "zyyxyx", strict=True):
        assert (j.tx, j.ty, j.tz) == pytest.approx((tx / 1000, ty / 1000, tz / 1000), abs=1e-15)
        assert (j.rx, j.ry, j.rz) == pytest.approx((rx * DEG, ry * DEG, rz * DEG), abs=1e-15)
        assert j.axis == axis and j.offset == 0.0


def test_motoman_up6_zero_pose_flange():
    desc = _load("motoman_up6")
    T = _fk(desc, desc.configurations["qz"])
    # D_i = Rot_i(q_i) Tx Ty Tz Rx Ry Rz: at q = 0 the only rotation is A6's Ry 90 deg, the
    # last factor, so the flange is at the plain sum of the table's translations:
    # x = 150 + 0 + 520 + 0 + 95 + 0 = 765 mm, y = 0, z = 450 + 310 + 130 = 890 mm.
    assert np.allclose(T[:3, 3], [0.765, 0.0, 0.890], atol=1e-12)
    # orientation Ry(90 deg): x6 = -z0, y6 = y0, z6 (approach) = +x0
    assert np.allclose(T[:3, :3], [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-12)


def test_motoman_up6_central_wrist():
    # The paper treats the UP6 as a "Knickarmroboter mit Zentralhand": the TCP position is
    # fixed by the main axes. Axes 4 and 5 meet (A4 has no translation) and axis 6 (x of
    # frame 5) passes through that point; the flange is 95 mm from it along the approach
    # vector, so p - 0.095 a depends on q1..q3 only. At q1..q3 = 0 it is (670, 0, 890) mm.
    desc = _load("motoman_up6")
    rng = np.random.default_rng(3)
    for q in _random_q(desc, rng, k=10):
        q2 = q.copy()
        q2[3:] = rng.uniform(-2, 2, 3)
        T1, T2 = _fk(desc, q), _fk(desc, q2)
        assert np.allclose(T1[:3, 3] - 0.095 * T1[:3, 2], T2[:3, 3] - 0.095 * T2[:3, 2], atol=1e-12)
    T = _fk(desc, [0, 0, 0, 0.3, -0.7, 1.1])
    assert np.allclose(T[:3, 3] - 0.095 * T[:3, 2], [0.670, 0.0, 0.890], atol=1e-12)


# -- Miskolc paper ------------------------------------------------------------------------------


def test_miskolc_rrrr_agrees_with_the_papers_inverse_kinematics():
    desc = _load("miskolc_rrrr")
    s1, a2, s4 = 0.50, 0.60, 0.50
    assert (desc.joints[0].d, desc.joints[1].a, desc.joints[3].d) == (s1, a2, s4)
    # ranges of section 2: alpha = 0..90 deg (q2), beta = 90..180 deg -> q3 in [-90, 0] deg
    assert np.allclose(desc.qlim[1], [0, math.pi / 2])
    assert np.allclose(desc.qlim[2], [-math.pi / 2, 0])
    rng = np.random.default_rng(4)
    for q in _random_q(desc, rng, k=50):
        T = _fk(desc, q)
        xc, yc, zc = T[:3, 3]
        # eq. (4): Theta1 = atan2(yc, xc)
        assert math.atan2(yc, xc) == pytest.approx(q[0], abs=1e-9)
        # eqs. (5)/(6): cos Theta3 = (r^2 + (zc - s1)^2 - a2^2 - s4^2) / (2 a2 s4) = D
        r, s = math.hypot(xc, yc), zc - s1
        D = (r**2 + s**2 - a2**2 - s4**2) / (2 * a2 * s4)
        assert D == pytest.approx(math.cos(q[2]), abs=1e-9)
        # eq. (7), upper elbow (the only posture the construction allows): atan2(-sqrt, D)
        th3 = math.atan2(-math.sqrt(max(0.0, 1 - D * D)), D)
        assert th3 == pytest.approx(q[2], abs=1e-6)
        # eq. (9): Theta2 = atan2(s, r) - atan2(s4 sin Theta3, a2 + s4 cos Theta3)
        th2 = math.atan2(s, r) - math.atan2(s4 * math.sin(th3), a2 + s4 * math.cos(th3))
        assert th2 == pytest.approx(q[1], abs=1e-6)
        # joint 4 does not move the origin of the end frame (section 4)
        q4 = q.copy()
        q4[3] += 1.0
        assert np.allclose(_fk(desc, q4)[:3, 3], T[:3, 3], atol=1e-12)
    # qz: both links horizontal: (a2 + s4, 0, s1) = (1.10, 0, 0.50)
    assert np.allclose(_fk(desc, desc.configurations["qz"])[:3, 3], [1.10, 0.0, 0.50])


# -- Puma 560 (Corke's Robotics Toolbox model) ---------------------------------------------------


def test_puma560_table():
    desc = _load("puma560")
    r = math.pi / 2
    assert [j.a for j in desc.joints] == [0, 0.4318, 0.0203, 0, 0, 0]
    assert [j.d for j in desc.joints] == [0.67183, 0, 0.15005, 0.4318, 0, 0]
    assert np.allclose([j.alpha for j in desc.joints], [r, 0, -r, r, -r, 0], atol=1e-15)
    assert np.allclose(
        desc.qlim / DEG,
        [[-160, 160], [-45, 225], [-225, 45], [-110, 170], [-100, 100], [-266, 266]],
    )
    c = desc.configurations
    assert np.allclose(c["qz"], np.zeros(6))
    assert np.allclose(c["qr"], [0, math.pi / 2, -math.pi / 2, 0, 0, 0])
    assert np.allclose(c["qn"], [0, math.pi / 4, -math.pi, 0, math.pi / 4, 0])


def test_puma560_known_poses():
    desc = _load("puma560")
    # qz, by hand: A1 = Rot_x(90) maps x1 = x0, z1 = -y0; A2 = Trans_x(a2) -> (a2, 0, 0);
    # A3 = Trans_z(d3) Trans_x(a3) Rot_x(-90) -> + d3 along -y0 and a3 along x0, frame 3 back
    # to the base orientation; A4 = Trans_z(d4) Rot_x(90) -> + d4 along z0; A5, A6 rotate only.
    # So p = (a2 + a3, -d3, d1 + d4) = (0.4521, -0.15005, 1.1036) m (d1 = 0.67183 m, the
    # Python toolbox's shoulder height), R = I.
    T = _fk(desc, desc.configurations["qz"])
    assert np.allclose(T[:3, 3], [0.4521, -0.15005, 0.67183 + 0.4318], atol=1e-12)
    assert np.allclose(T[:3, :3], np.eye(3), atol=1e-12)
    # qr (arm straight up): upper arm a2 and forearm d4 both along z0:
    # p = (a3, -d3, d1 + a2 + d4) = (0.0203, -0.15005, 1.5354) m
    T = _fk(desc, desc.configurations["qr"])
    assert np.allclose(T[:3, 3], [0.0203, -0.15005, 0.67183 + 0.8636], atol=1e-12)
