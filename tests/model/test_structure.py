"""Structure detection of serial chains (deltagen/model/structure.py) and the shared
geometry it rests on (deltagen/geometry/axes.py, deltagen/geometry/limits.py).

Evidence: the bundled arms' published structures (central wrists of the Puma 560, Motoman
UP6 and Manutec r15, the Miskolc RRRR elbow arm, the SCARAs; the offset-wrist Puma has
none); invariance of what is detected under a base / tool transform and under a rewrite of
the same arm in another convention (standard DH -> universal coordinates, -> modified DH);
the independent numpy reference (reference.joint_axes, reference.fk); hand-computed values
for the line and joint-limit helpers.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import sympy as sp
from helpers import compiled_fit_angle

from deltagen.geometry import axes as geo
from deltagen.geometry import limits
from deltagen.model import structure as st
from deltagen.model.serial import SerialDescription, transform
from deltagen.paths import robots_dir
from deltagen.reference import serial as reference

EXPECTED = {
    "puma560": st.SphericalWrist6R,
    "motoman_up6": st.SphericalWrist6R,
    "manutec_r15": st.SphericalWrist6R,
    "miskolc_rrrr": st.Elbow4R,
    "lecture_scara": st.PlanarArm,
    "manutec_h5": st.PlanarArm,
    "bosch_sr800": st.PlanarArm,
    "puma560_offset_wrist": None,
    "lecture_prp": None,
    "gantry_xyz_wrist": st.GantryArm,
    "gantry_xyz_ac": st.GantryArm,
    "palletiser_xyzc": st.GantryArm,
}
CENTRAL_WRIST = {"puma560", "motoman_up6", "manutec_r15", "gantry_xyz_wrist"}
PI = math.pi


def _load(name: str) -> SerialDescription:
    return SerialDescription.from_toml(robots_dir() / f"{name}.toml")


def _rows(a, alpha, d, convention="standard", **extra):
    return SerialDescription.from_rows(
        [dict(a=x, alpha=y, d=z) for x, y, z in zip(a, alpha, d)],
        convention,
        name=extra.pop("name", "arm"),
        **extra,
    )


def _puma_like(changes=None):
    """The Puma 560 of robots/puma560.toml as rows, with changes {(joint, key): value}."""
    a = [0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0]
    alpha = [PI / 2, 0.0, -PI / 2, PI / 2, -PI / 2, 0.0]
    d = [0.67183, 0.0, 0.15005, 0.4318, 0.0, 0.0]
    rows = [dict(a=x, alpha=y, d=z) for x, y, z in zip(a, alpha, d)]
    for (i, key), value in (changes or {}).items():
        rows[i][key] = value
    return SerialDescription.from_rows(rows, "standard", name="variant")


def _ur5():
    """UR5 (standard DH, Universal Robots' published table): axes 2, 3, 4 parallel."""
    return _rows(
        [0.0, -0.425, -0.39225, 0.0, 0.0, 0.0],
        [PI / 2, 0.0, 0.0, PI / 2, -PI / 2, 0.0],
        [0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823],
        name="ur5",
    )


def _as_universal(desc: SerialDescription) -> SerialDescription:
    """A standard-DH arm rewritten in universal coordinates: Rz(q) Tz(d) Tx(a) Rx(alpha) =
    Rz(q) Tx(a) Ty(0) Tz(d) Rx(alpha) (translations commute); joint axis z. A prismatic
    joint (theta = 0, d its variable) slides along z the same way."""
    assert desc.convention == "standard"
    joints = []
    for j in desc.joints:
        assert j.revolute or j.theta == 0.0
        joints.append(
            dataclasses.replace(
                j,
                a=0.0,
                alpha=0.0,
                d=0.0,
                theta=0.0,
                tx=j.a,
                ty=0.0,
                tz=j.d,
                rx=j.alpha,
                ry=0.0,
                rz=0.0,
                axis="z",
            )
        )
    return dataclasses.replace(
        desc, name=f"{desc.name}_uc", convention="universal", joints=tuple(joints)
    )


def _as_modified(desc: SerialDescription) -> SerialDescription:
    """A standard-DH arm in Craig's modified DH: row i takes a_{i-1}, alpha_{i-1} (row 1: 0),
    and Tx(a_n) Rx(alpha_n) of the last link moves into the tool."""
    assert desc.convention == "standard"
    js = desc.joints
    joints = [
        dataclasses.replace(j, a=js[i - 1].a if i else 0.0, alpha=js[i - 1].alpha if i else 0.0)
        for i, j in enumerate(js)
    ]
    tool = transform((js[-1].a, 0.0, 0.0), (js[-1].alpha, 0.0, 0.0)) @ desc.tool
    return dataclasses.replace(
        desc, name=f"{desc.name}_mdh", convention="modified", joints=tuple(joints), tool=tool
    )


def _same_line(ax1, ax2, i, tol=1e-12):
    """Axis i of both is the same line with the same direction."""
    w1, w2 = ax1.directions[i], ax2.directions[i]
    d = ax2.points[i] - ax1.points[i]
    return np.allclose(w1, w2, atol=tol) and np.linalg.norm(d - (d @ w1) * w1) < tol * max(
        1.0, ax1.scale
    )


def _elbow_invariants(s):
    """What an elbow arm's closed form is made of, independent of where the description puts
    the points o_i along their axes."""
    out = dict(
        wrist=s.wrist,
        ex=s.ex,
        ey=s.ey,
        ez=s.ez,
        upper=s.upper,
        lower=s.lower,
        sign3=s.sign3,
        front=s.front,
        bend=s.bend,
        cos_12=s.cos_12,
        sin_12=s.sin_12,
    )
    if isinstance(s, st.SphericalWrist6R):
        out.update(wrist_ref=s.wrist_ref, cos_45=s.cos_45, cos_56=s.cos_56, normal_45=s.normal_45)
    else:
        out.update(roll_ref=s.roll_ref)
    return out


# -- detection on the bundled arms ---------------------------------------------------------


@pytest.mark.parametrize("name", list(EXPECTED))
def test_bundled_arms(name):
    desc = _load(name)
    found = st.detect(desc)
    if EXPECTED[name] is None:
        assert found is None
    else:
        assert type(found) is EXPECTED[name]
        assert found.kind in ("planar", "elbow_4r", "spherical_wrist_6r", *st.GANTRY_KINDS.values())
        assert found.axes.n == desc.n
        np.testing.assert_array_equal(found.qlim, desc.qlim)
    ax = st.joint_axes(desc)
    assert ax.matches(desc)
    if desc.n == 6:
        assert (st.central_wrist(ax) is not None) == (name in CENTRAL_WRIST)


def test_joint_axes_agree_with_the_reference():
    """Composed from the description's own transforms, bit for bit those of the
    independent reference (the same elementary products)."""
    for name in EXPECTED:
        desc = _load(name)
        ax = st.joint_axes(desc)
        o, w = reference.joint_axes(desc, np.zeros((1, desc.n)))
        T, _ = reference.fk(desc, np.zeros((1, desc.n)))
        np.testing.assert_array_equal(ax.points, o[0])
        np.testing.assert_allclose(ax.directions, w[0], atol=1e-15)
        np.testing.assert_array_equal(ax.T0, T[0])
        q = np.random.default_rng(3).uniform(-3, 3, (50, desc.n))
        R, p = ax.fk(q)
        Tq, _ = reference.fk(desc, q)
        assert np.abs(R - Tq[:, :3, :3]).max() < 1e-12
        assert np.abs(p - Tq[:, :3, 3]).max() < 1e-12 * ax.scale


def test_puma560_constants():
    """Hand-checked: the Puma's wrist centre at q = 0 is (a2 + a3, -d3, d1 + d4) (the flange
    of robots/puma560.toml's comment: d6 = 0), the shoulder offset is d3."""
    s = st.detect(_load("puma560"))
    np.testing.assert_allclose(s.wrist, [0.4318 + 0.0203, -0.15005, 0.67183 + 0.4318], atol=1e-12)
    np.testing.assert_allclose(s.ez, [0, 0, 1], atol=1e-15)
    assert abs(s.cos_12) < 1e-15 and abs(s.sin_12) == pytest.approx(1.0)
    assert repr(s) == "SphericalWrist6R('puma560')"
    assert abs(s.w2_offset) == pytest.approx(0.15005)
    assert s.sign3 == 1.0
    np.testing.assert_array_equal(s.front, [1, 1, -1, -1])
    assert s.configs[0] == "front_up_noflip" and len(s.configs) == 8
    assert s.cos_45 == pytest.approx(0.0, abs=1e-15) and s.cos_56 == pytest.approx(0.0, abs=1e-15)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.sign3 = -1.0
    with pytest.raises(ValueError):
        s.wrist[0] = 1.0  # read-only arrays


def test_scara_constants():
    s = st.detect(_load("bosch_sr800"))
    assert (s.first, s.second, s.roll, s.lift) == (0, 1, 3, 2)
    assert np.all(np.abs(s.signs) == 1.0)
    np.testing.assert_allclose(np.abs(s.u), [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(s.plane @ s.u, 0.0, atol=1e-15)
    assert s.upper[1] == pytest.approx(0.0, abs=1e-15)  # e1 points from axis 1 to axis 2
    s2 = st.detect(_load("lecture_scara"))
    assert s2.roll is None and s2.lift is None and s2.position_only_ok


# -- invariance ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name",
    [
        "puma560",
        "manutec_r15",
        "miskolc_rrrr",
        "bosch_sr800",
        "lecture_scara",
        "puma560_offset_wrist",
    ],
)
def test_base_transform_moves_everything_rigidly(name):
    desc = _load(name)
    B = transform((0.3, -0.2, 0.5), (0.2, -0.1, 0.7))
    moved = dataclasses.replace(desc, base=B @ desc.base)
    a, b = st.detect(desc), st.detect(moved)
    assert type(a) is type(b)
    if a is None:
        return
    R = B[:3, :3]
    np.testing.assert_allclose(b.axes.directions, a.axes.directions @ R.T, atol=1e-12)
    if isinstance(a, st.PlanarArm):
        np.testing.assert_allclose(b.u, R @ a.u, atol=1e-12)
        np.testing.assert_allclose(b.point, R @ a.point + B[:3, 3], atol=1e-12)
        np.testing.assert_allclose(b.upper, a.upper, atol=1e-12)
        np.testing.assert_allclose(b.lower, a.lower, atol=1e-12)
        np.testing.assert_array_equal(b.signs, a.signs)
        return
    np.testing.assert_allclose(b.wrist, R @ a.wrist + B[:3, 3], atol=1e-12)
    for key in ("ex", "ey", "ez"):
        np.testing.assert_allclose(getattr(b, key), R @ getattr(a, key), atol=1e-12)
    for key in ("upper", "lower"):
        np.testing.assert_allclose(getattr(b, key), getattr(a, key), atol=1e-12)
    np.testing.assert_array_equal(b.bend, a.bend)
    assert b.configs == a.configs


@pytest.mark.parametrize("name", ["puma560", "manutec_r15", "motoman_up6", "bosch_sr800"])
def test_tool_transform_keeps_the_structure(name):
    desc = _load(name)
    tool = transform((0.01, -0.02, 0.12), (0.3, 0.4, -0.5))
    a, b = st.detect(desc), st.detect(dataclasses.replace(desc, tool=desc.tool @ tool))
    assert type(a) is type(b) and a.configs == b.configs
    np.testing.assert_allclose(b.axes.directions, a.axes.directions, atol=1e-15)
    if isinstance(a, st.SphericalWrist6R):
        np.testing.assert_allclose(b.wrist, a.wrist, atol=1e-12)  # the wrist centre stays
    else:  # the SCARA's roll axis keeps P; the tool point left it
        assert not b.position_only_ok


@pytest.mark.parametrize(
    "name",
    [
        "puma560",
        "manutec_r15",
        "miskolc_rrrr",
        "lecture_scara",
        "bosch_sr800",
        "manutec_h5",
        "puma560_offset_wrist",
    ],
)
@pytest.mark.parametrize("rewrite", [_as_universal, _as_modified], ids=["universal", "modified"])
def test_the_convention_does_not_matter(name, rewrite):
    """The same arm in another convention: the same lines, so the same structure and the
    same constants of its closed form."""
    desc = _load(name)
    if rewrite is _as_universal and not all(j.revolute or j.theta == 0 for j in desc.joints):
        pytest.skip("a prismatic joint with a constant theta has no universal rewrite here")
    other = rewrite(desc)
    q = np.random.default_rng(5).uniform(-2, 2, (20, desc.n))
    assert np.abs(reference.fk(desc, q)[0] - reference.fk(other, q)[0]).max() < 1e-12
    a, b = st.detect(desc), st.detect(other)
    assert type(a) is type(b)
    ax_a, ax_b = st.joint_axes(desc), st.joint_axes(other)
    for i in range(desc.n):
        assert _same_line(ax_a, ax_b, i)
    np.testing.assert_allclose(ax_b.T0, ax_a.T0, atol=1e-12)
    if a is None:
        return
    assert a.configs == b.configs
    if isinstance(a, st.PlanarArm):
        for key in ("u", "signs", "plane", "point", "upper", "lower"):
            np.testing.assert_allclose(getattr(b, key), getattr(a, key), atol=1e-12, err_msg=key)
        assert (a.first, a.second, a.roll, a.lift) == (b.first, b.second, b.roll, b.lift)
        return
    ia, ib = _elbow_invariants(a), _elbow_invariants(b)
    for key in ia:
        np.testing.assert_allclose(ib[key], ia[key], atol=1e-12, err_msg=key)


# -- what is refused -----------------------------------------------------------------------


@pytest.mark.parametrize(
    "changes",
    [
        {(4, "a"): 0.05},  # axis 6 misses the common point of axes 4, 5
        {(4, "d"): 0.04},  # axis 6 meets axis 5 elsewhere than axis 4 does
        {(1, "alpha"): math.radians(10)},  # axes 2 and 3 not parallel
        {(1, "alpha"): 1e-7},  # nearly parallel: neither parallel nor clearly not
        {(0, "alpha"): 0.0},  # axis 1 parallel to axis 2
        {(1, "a"): 0.0, (2, "a"): 0.0, (2, "d"): 0.0},  # axes 2 and 3 the same line
    ],
    ids=[
        "wrist_a5",
        "wrist_d5",
        "axes23_skew",
        "axes23_nearly",
        "axes12_parallel",
        "axes23_collinear",
    ],
)
def test_six_axis_arms_without_a_closed_form(changes):
    assert st.detect(_puma_like(changes)) is None


def test_other_refusals():
    assert st.detect(_puma_like()) is not None  # the unchanged rows are a Puma
    prismatic = _puma_like()
    joints = list(prismatic.joints)
    joints[5] = dataclasses.replace(joints[5], type="prismatic")
    assert st.detect(dataclasses.replace(prismatic, joints=tuple(joints))) is None
    # a planar 3R arm whose third axis tilts
    assert st.detect(_rows([0.4, 0.3, 0.1], [0, 0, 0], [0, 0, 0])) is not None
    assert st.detect(_rows([0.4, 0.3, 0.1], [0, 0.3, 0], [0, 0, 0])) is None
    # two parallel revolute axes on one line (no planar arm), a 5R arm, one joint
    assert st.detect(_rows([0.0, 0.3], [0, 0], [0.1, 0])) is None
    assert st.detect(_rows([0.1] * 5, [PI / 2] * 5, [0.1] * 5)) is None
    assert st.detect(_rows([0.3], [0.0], [0.0])) is None
    # no central wrist: not a SphericalWrist6R, but the UR structure (three parallel axes)
    assert isinstance(st.detect(_ur5()), st.ParallelTriple6R)


# -- general predicates --------------------------------------------------------------------


def test_predicates_of_a_puma_and_a_ur5():
    puma = st.joint_axes(_load("puma560"))
    # at q = 0 axes 1, 4, 6 point along z and axes 2, 3, 5 along -y
    assert st.parallel_pairs(puma) == [(0, 3), (0, 5), (1, 2), (1, 4), (2, 4), (3, 5)]
    assert st.parallel_runs(puma) == [] and st.parallel_runs(puma, length=2) == [1]
    np.testing.assert_allclose(
        st.central_wrist(puma), st.detect(_load("puma560")).wrist, atol=1e-12
    )
    assert st.common_point_of(puma, [1, 2]) is None  # parallel and distinct
    np.testing.assert_allclose(
        st.common_point_of(puma, [0, 1]), [0, 0, 0.67183], atol=1e-12
    )  # axes 1 and 2 meet at the shoulder
    ur5 = st.joint_axes(_ur5())
    assert st.parallel_runs(ur5) == [1]  # axes 2, 3, 4
    assert st.parallel_runs(ur5, length=2) == [1, 2]
    assert st.central_wrist(ur5) is None
    assert (1, 2) in st.parallel_pairs(ur5) and (1, 3) in st.parallel_pairs(ur5)


# -- geometry/axes.py ----------------------------------------------------------------------


def test_parallel_and_not_parallel():
    z = np.array([0.0, 0.0, 1.0])
    assert geo.parallel(z, -z)
    tilt = lambda a: np.array([math.sin(a), 0.0, math.cos(a)])  # noqa: E731
    assert geo.parallel(z, tilt(5e-10)) and not geo.parallel(z, tilt(5e-9))
    assert not geo.not_parallel(z, tilt(5e-7)) and geo.not_parallel(z, tilt(2e-6))
    assert geo.not_parallel(z, np.array([1.0, 0, 0]))
    assert geo.PARALLEL_TOL == 1e-9 and geo.NONPARALLEL_TOL == 1e-6 and geo.LENGTH_TOL == 1e-9


def test_line_distance_and_foot():
    z, x = np.array([0.0, 0, 1]), np.array([1.0, 0, 0])
    o = np.zeros(3)
    assert geo.line_distance(o, z, np.array([0.0, 2, 0]), x) == pytest.approx(2.0)
    assert geo.line_distance(o, z, np.array([3.0, 4, 7]), -z) == pytest.approx(5.0)
    assert geo.line_distance(o, z, np.array([0.0, 0, 5]), x) == pytest.approx(0.0)
    np.testing.assert_allclose(geo.foot(np.array([1.0, 2, 3]), o, z), [0, 0, 3])
    np.testing.assert_allclose(geo.unit([3.0, 0, 4]), [0.6, 0, 0.8])


def test_common_point():
    p = np.array([1.0, 2.0, 3.0])
    dirs = [geo.unit(v) for v in ([1, 0, 0], [0, 1, 0], [1, 1, 1])]
    x, dist = geo.common_point([p - 2 * dirs[0], p + dirs[1], p + 5 * dirs[2]], dirs)
    np.testing.assert_allclose(x, p, atol=1e-14)
    assert dist < 1e-14
    # the x axis and a line along y at z = 1: nearest point (0, 0, 0.5), each 0.5 away
    x, dist = geo.common_point(
        [np.zeros(3), np.array([0.0, 0, 1])], [np.array([1.0, 0, 0]), np.array([0.0, 1, 0])]
    )
    np.testing.assert_allclose(x, [0, 0, 0.5], atol=1e-15)
    assert dist == pytest.approx(0.5)
    assert (
        geo.meet(
            [np.zeros(3), np.array([0.0, 0, 1])],
            [np.array([1.0, 0, 0]), np.array([0.0, 1, 0])],
            0.4,
        )
        is None
    )
    o = np.array([[np.zeros(3), np.array([0.0, 0, 1])]] * 2)
    w = np.array([[[1.0, 0, 0], [0.0, 1, 0]]] * 2)
    np.testing.assert_allclose(geo.common_points(o, w), [[0, 0, 0.5]] * 2, atol=1e-15)


# -- geometry/limits.py --------------------------------------------------------------------


def test_wrap_to_pi():
    np.testing.assert_allclose(
        limits.wrap_to_pi(np.array([PI, -PI, 1.5 * PI, 7.0, 0.0])),
        [-PI, -PI, -0.5 * PI, 7.0 - 2 * PI, 0.0],
        atol=1e-15,
    )
    assert limits.TWO_PI == 2 * PI and limits.LIMIT_TOL == 1e-10
    assert limits.SHIFTS == (1, -1, 2, -2)


@pytest.mark.parametrize(
    "value, lo, hi, expected, inside",
    [
        (-PI / 2, 0.0, 2 * PI, 1.5 * PI, True),  # +2 pi
        (3.0, -4.0, -2.0, 3.0 - 2 * PI, True),  # -2 pi
        (-1.0, 10.0, 12.0, -1.0 + 4 * PI, True),  # +4 pi (the third shift)
        (1.0 + 4 * PI, -0.5, 1.5, 1.0, True),  # wrapped into [-pi, pi) first
        (2.0, -0.5, 0.5, 2.0, False),  # nothing fits: stays in [-pi, pi)
        (5.0, -0.5, 0.5, 5.0 - 2 * PI, False),
        (1.0 + 5e-11, -1.0, 1.0, 1.0, True),  # within LIMIT_TOL: clipped onto the limit
        (1.0 + 1e-9, -1.0, 1.0, 1.0 + 1e-9, False),
        (4.0, -np.inf, np.inf, 4.0 - 2 * PI, True),  # no limits: [-pi, pi)
        (3.5, -4.0, 4.0, 3.5 - 2 * PI, True),  # inside, yet wrapped: the closed forms' rule
    ],
)
def test_fit_limits_revolute(value, lo, hi, expected, inside):
    q, ok = limits.fit_limits(np.array([[value]]), np.array([[lo, hi]]), [True])
    assert q[0, 0] == pytest.approx(expected, abs=1e-14)
    assert bool(ok[0]) == inside


def test_fit_limits_prismatic_and_shapes():
    qlim = np.array([[0.0, 5.0], [-PI, PI]])
    q = np.array([[4.0, 7.0], [6.0, 1.0], [5.0 + 1e-13, 0.0]])
    out, inside = limits.fit_limits(q, qlim, [False, True])
    np.testing.assert_allclose(out, [[4.0, 7.0 - 2 * PI], [6.0, 1.0], [5.0, 0.0]], atol=1e-15)
    np.testing.assert_array_equal(inside, [True, False, True])
    np.testing.assert_array_equal(q[0], [4.0, 7.0])  # the input is not changed
    out, inside = limits.fit_limits(np.zeros((2, 3, 2)), qlim, [False, True])
    assert out.shape == (2, 3, 2) and inside.shape == (2, 3) and inside.all()


def test_shift_into_limits():
    lo, hi = np.array([-PI, -4.0, -1.0, -1.0]), np.array([PI, 4.0, 1.0, 1.0])
    wraps = np.array([True, True, True, False])
    q = np.array([7.0, 3.5, 10.0, 3.0])
    np.testing.assert_allclose(
        limits.shift_into_limits(q, lo, hi, wraps), [7.0 - 2 * PI, 3.5, 10.0, 3.0]
    )  # 10: no shift brings it in
    q = np.array([[-7.0, -9.0, 0.5, 0.0]])
    np.testing.assert_allclose(
        limits.shift_into_limits(q, lo, hi, wraps), [[-7.0 + 2 * PI, -9.0 + 2 * PI, 0.5, 0.0]]
    )


def test_the_c_kernel_fit_is_the_numpy_fit(tmp_path):
    """The limit fit of the ik_all emitter (SymPy statements around the runtime's C
    deltagen_fit_angle, compiled here), evaluated in double precision, is
    geometry.limits.fit_limits: the same constants (taken from there), the same decisions,
    the same values up to the rounding of the wrap (C: x - 2 pi floor((x + pi) / 2 pi),
    numpy: mod(x + pi, 2 pi) - pi; they differ by an ulp of pi at most)."""
    from deltagen.derive.serial import ik_closed_form as ikc
    from deltagen.derive.serial.ik_recipes import Angle

    modules = [{"FitAngle": compiled_fit_angle(tmp_path)}, "numpy"]

    assert ikc.LIMIT_TOL is limits.LIMIT_TOL and ikc.SHIFTS is limits.SHIFTS
    found = st.detect(_load("bosch_sr800"))  # revolute joints with limits and a prismatic one
    builder = ikc.IKKernelBuilder(found, chain=None)
    builder.tape.stage("fit")
    theta, d = sp.Symbol("theta", real=True), sp.Symbol("d", real=True)
    outs = []
    for i in range(found.axes.n):
        a = Angle(theta, sp.cos(theta), sp.sin(theta)) if found.axes.revolute[i] else d
        outs.append(builder._fit_limits(f"f{i}", i, a))
    rng = np.random.default_rng(1)
    values = np.concatenate(
        [
            rng.uniform(-15, 15, 300),
            found.qlim[np.isfinite(found.qlim)],
            found.qlim[np.isfinite(found.qlim)] + 5e-13,
        ]
    )
    env = {theta: values, d: values}
    for _, assignments in builder.tape.stages:
        for sym, expr in assignments:
            args = sorted(expr.free_symbols, key=str)
            env[sym] = np.broadcast_to(
                sp.lambdify(args, expr, modules)(*[env[s] for s in args]), values.shape
            )
    for i, (value, fits) in enumerate(outs):
        expected, inside = limits.fit_limits(
            values[:, None], found.qlim[i : i + 1], found.axes.revolute[i : i + 1]
        )
        np.testing.assert_allclose(env[value], expected[:, 0], rtol=0, atol=1e-15)
        np.testing.assert_array_equal(env[fits] if fits in env else bool(fits), inside)
