"""5-axis NC machines (deltagen/model/five_axis.py): every layout and rotary pair, compiled
against the numpy reference and against independent evidence:

* a homogeneous-transform chain composed here (numpy 4x4 products: the table turned the
  other way for a table axis, then inverted with np.linalg.inv);
* LinuxCNC's published kinematics formulas, rewritten here from LinuxCNC's
  src/emc/kinematics/trtfuncs_math.h (xyzac-trt and xyzbc-trt, conventional_directions = 1),
  5axiskins_math.h (head-head BC bridge mill) and maxkins_math.h (table-head BC), with the
  mapping of their parameters onto ours stated at each test;
* round trips: fk(ik) = target to 1e-12 for every branch, ik(fk) = joints;
* the singular pose (tool axis along C): SINGULAR, finite, C held;
* the C-axis wrap: a path circling the C axis gives a continuous C.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltagen import FiveAxisMachine, GeometryError, InputError
from deltagen import status as st
from deltagen.api.five_axis import bundled_machines
from deltagen.model.five_axis import LAYOUTS, ROTARIES, MachineDescription

CONFIGS = [(layout, rotary) for layout in LAYOUTS for rotary in ROTARIES]
RNG_SEED = 7


def _geometry(layout, seed):
    """Random offsets of the size of a machine (0.1 m), zero where the layout has none."""
    rng = np.random.default_rng(seed)
    g = dict(
        tool_length=float(rng.uniform(0.03, 0.15)),
        head_pivot=tuple(rng.uniform(-0.1, 0.1, 3)),
        spindle_offset=tuple(rng.uniform(-0.1, 0.1, 3)),
    )
    if layout != "head-head":
        g["c_pivot"] = tuple(rng.uniform(-0.1, 0.1, 3))
    if layout == "table-table":
        g["tilt_pivot"] = tuple(rng.uniform(-0.1, 0.1, 3))
    return g


@pytest.fixture(scope="module")
def machines():
    """(layout, rotary) -> (compiled, reference) of random geometry; one compiled core."""
    out = {}
    for k, (layout, rotary) in enumerate(CONFIGS):
        m = FiveAxisMachine(layout, rotary, **_geometry(layout, k))
        out[layout, rotary] = (m, m.with_backend("reference"))
    return out


def _joints(n, seed=RNG_SEED):
    rng = np.random.default_rng(seed)
    j = rng.uniform(-1.0, 1.0, (n, 5)) * [0.4, 0.4, 0.4, math.pi, math.pi]
    return j


def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


# -- the independent homogeneous-transform chain ----------------------------------------


def _trans(v):
    T = np.eye(4)
    T[:3, 3] = v
    return T


def _rot(axis, angle):
    c, s = math.cos(angle), math.sin(angle)
    T = np.eye(4)
    i, k = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    T[i, i], T[i, k], T[k, i], T[k, k] = c, -s, s, c
    return T


def _about(point, axis, angle):
    """A rotation about the line through ``point`` along ``axis``."""
    return _trans(point) @ _rot(axis, angle) @ _trans(-np.asarray(point))


def chain_4x4(desc: MachineDescription, j):
    """Tool tip and tool axis in W from 4x4 products: the tool frame in the machine frame
    M, the workpiece frame W in M (a table axis turns the table by -angle: ISO 841 counts
    the tool's motion relative to the workpiece), W^-1 M tool."""
    x, y, z, t, c = j
    tilt = {"A": "x", "B": "y"}[desc.tilt_axis]
    head_c = _rot("z", c) if desc.layout == "head-head" else np.eye(4)
    head_t = _rot(tilt, t) if desc.layout != "table-table" else np.eye(4)
    tool = (
        _trans([x, y, z])
        @ head_c
        @ _trans(desc.head_pivot)
        @ head_t
        @ _trans(desc.spindle_offset)
        @ _trans([0.0, 0.0, -desc.tool_length])
    )
    work = np.eye(4)
    if desc.layout == "table-table":
        work = _about(desc.tilt_pivot, tilt, -t) @ _about(desc.c_pivot, "z", -c)
    elif desc.layout == "table-head":
        work = _about(desc.c_pivot, "z", -c)
    T = np.linalg.inv(work) @ tool
    return T[:3, 3], T[:3, 2]


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: f"{c[0]}-{c[1]}")
def test_fk_equals_the_homogeneous_transform_chain(machines, config):
    compiled, reference = machines[config]
    j = _joints(200)
    p, d = compiled.fk(j)
    pr, dr = reference.fk(j)
    for i in range(len(j)):
        p4, d4 = chain_4x4(compiled.description, j[i])
        np.testing.assert_allclose(p[i], p4, atol=1e-14 * 10, rtol=0)
        np.testing.assert_allclose(d[i], d4, atol=1e-14 * 10, rtol=0)
    np.testing.assert_allclose(pr, p, atol=1e-13, rtol=0)
    np.testing.assert_allclose(dr, d, atol=1e-13, rtol=0)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-15)


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: f"{c[0]}-{c[1]}")
def test_every_branch_round_trips_to_1e12(machines, config):
    """fk(ik_all(p, d)) = (p, d) for both branches, compiled and reference; the branches
    are the two signs of sin(tilt)."""
    j = _joints(2000)
    compiled, reference = machines[config]
    p, d = compiled.fk(j)
    prev = j + [0.0, 0.0, 0.0, 0.0, 0.3]  # no tie: the other branch's C is pi - 0.3 away
    for machine in (compiled, reference):
        both, valid = machine.ik_all(p, d, prev)
        assert both.shape == (2000, 2, 5) and valid.all()
        assert np.all(np.sin(both[:, 0, 3]) >= -1e-15) and np.all(np.sin(both[:, 1, 3]) <= 1e-15)
        for k in range(2):
            p2, d2 = compiled.fk(both[:, k])
            np.testing.assert_allclose(p2, p, atol=1e-12, rtol=0)
            np.testing.assert_allclose(d2, d, atol=1e-12, rtol=0)
    jc, _ = compiled.ik_all(p, d, prev)
    jr, _ = reference.ik_all(p, d, prev)
    np.testing.assert_allclose(jc, jr, atol=1e-12, rtol=0)


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: f"{c[0]}-{c[1]}")
def test_ik_recovers_the_joints_and_the_turn_of_c(machines, config):
    """ik(fk(j), previous = j) = j, with C on the previous C's turn: j's C + 2 pi k is
    returned when the previous C is there."""
    compiled, reference = machines[config]
    j = _joints(1000)
    p, d = compiled.fk(j)
    for machine in (compiled, reference):
        np.testing.assert_allclose(machine.ik(p, d, j), j, atol=1e-12, rtol=0)
        turned = j + [0.0, 0.0, 0.0, 0.0, 4 * math.pi]
        np.testing.assert_allclose(machine.ik(p, d, turned), turned, atol=1e-11, rtol=0)
    # from zeros: the joints mod 2 pi in C, or the other branch
    out = compiled.ik(p, d)
    same = np.abs(_wrap(out[:, 3] - j[:, 3])) < 1e-9
    np.testing.assert_allclose(out[same, :3], j[same, :3], atol=1e-12)
    np.testing.assert_allclose(_wrap(out[same, 4] - j[same, 4]), 0.0, atol=1e-12)
    assert np.all(np.abs(out[:, 4]) <= math.pi + 1e-12)
    assert same.mean() > 0.2 and (~same).mean() > 0.2  # both branches occur


def test_single_pose_path_gives_the_batch_bits(machines):
    compiled, _ = machines["table-table", "AC"]
    j = _joints(5)
    p, d = compiled.fk(j)
    for i in range(5):
        pi, di = compiled.fk(j[i])
        assert np.array_equal(pi, p[i]) and np.array_equal(di, d[i])
        assert np.array_equal(compiled.ik(p[i], d[i], j[i]), compiled.ik(p, d, j)[i])
        assert np.array_equal(
            compiled.ik(list(p[i]), list(d[i])), compiled.ik(p[i : i + 1], d[i : i + 1])[0]
        )


# -- LinuxCNC's published formulas ---------------------------------------------------------


def linuxcnc_trt_forward(tilt_axis, joints, rot_point, offset, tool_offset):
    """LinuxCNC trtfuncs_math.h, xyzac_forward_math / xyzbc_forward_math with
    conventional_directions = 1, rewritten: with u = J - R - D (R the rotation point, D the
    offsets (0, y_offset, z_offset + tool_offset) for AC, (x_offset, 0, z_offset +
    tool_offset) for BC), world = R + Rz(c) (D + R_tilt(a) u), Rz and R_tilt the usual
    right-hand rotations (the x, y rows expanded in the source)."""
    x, y, z, a, c = joints
    dx, dy, dz = offset[0], offset[1], offset[2] + tool_offset
    if tilt_axis == "A":
        dx = 0.0
    else:
        dy = 0.0
    u = np.array([x - dx, y - dy, z - dz]) - rot_point
    ca, sa, cc, sc = math.cos(a), math.sin(a), math.cos(c), math.sin(c)
    if tilt_axis == "A":
        v = np.array([u[0], ca * u[1] - sa * u[2], sa * u[1] + ca * u[2]])
    else:
        v = np.array([ca * u[0] + sa * u[2], u[1], -sa * u[0] + ca * u[2]])
    v = v + [dx, dy, dz]
    return np.array([cc * v[0] - sc * v[1], sc * v[0] + cc * v[1], v[2]]) + rot_point


def linuxcnc_xyzac_inverse(world, a, c, rot_point, y_offset, dz):
    """LinuxCNC trtfuncs_math.h, xyzac_inverse_math (conventional_directions = 1), its
    three rows rewritten term by term (dz = z_offset + tool_offset)."""
    wx, wy, wz = np.asarray(world) - rot_point
    ca, sa, cc, sc = math.cos(a), math.sin(a), math.cos(c), math.sin(c)
    jx = cc * wx + sc * wy
    jy = -sc * ca * wx + cc * ca * wy + sa * wz - ca * y_offset - sa * dz + y_offset
    jz = sc * sa * wx - cc * sa * wy + ca * wz + sa * y_offset - ca * dz + dz
    return np.array([jx, jy, jz]) + rot_point


@pytest.mark.parametrize("rotary", ROTARIES)
def test_trunnion_matches_linuxcnc_trt_kins(rotary):
    """Our table-table machine with c_pivot = LinuxCNC's rotation point R and tilt_pivot =
    R + (x|y_offset, z_offset): its tool tip equals LinuxCNC's world point moved down by the
    tool length (LinuxCNC's world z of the trt modules is the tool-length-compensated one:
    tool_offset enters only through the pivot distance dz, and world = joints at zero
    angles)."""
    R = np.array([0.012, -0.031, 0.004])
    offset = np.array([0.021, 0.017, 0.063])  # x_offset (BC), y_offset (AC), z_offset
    L = 0.085
    tilt_offset = [offset[0], 0.0, offset[2]] if rotary == "BC" else [0.0, offset[1], offset[2]]
    machine = FiveAxisMachine(
        "table-table", rotary, tool_length=L, c_pivot=R, tilt_pivot=R + tilt_offset
    )
    j = _joints(300)
    p, _ = machine.fk(j)
    for i in range(len(j)):
        world = linuxcnc_trt_forward(rotary[0], j[i], R, offset, L)
        np.testing.assert_allclose(p[i], world - [0.0, 0.0, L], atol=1e-14 * 10, rtol=0)
    if rotary == "AC":  # the inverse's rows too: the joints x, y, z of world and angles
        d = machine.fk(j)[1]
        back = machine.ik(p, d, j)
        for i in range(len(j)):
            joints = linuxcnc_xyzac_inverse(
                p[i] + [0.0, 0.0, L], j[i, 3], j[i, 4], R, offset[1], offset[2] + L
            )
            np.testing.assert_allclose(back[i, :3], joints, atol=1e-13, rtol=0)


def test_head_head_matches_linuxcnc_5axiskins():
    """LinuxCNC 5axiskins_math.h (XYZBC bridge mill), rewritten: the tool tip is
    J + (0, 0, P) + (P + W) s2r(C, 180 deg - B), s2r the spherical-to-rectangular
    conversion (sin(phi) cos(theta), sin(phi) sin(theta), cos(phi)); P the pivot length, W
    the tool length. Ours: head_pivot (0, 0, P), spindle_offset (0, 0, -P),
    tool_length W; 5axiskins' B turns the other way round y (b = -tilt)."""
    P, W = 0.15, 0.06
    machine = FiveAxisMachine(
        "head-head", "BC", tool_length=W, head_pivot=(0, 0, P), spindle_offset=(0, 0, -P)
    )
    j = _joints(300)
    p, d = machine.fk(j)
    for i in range(len(j)):
        x, y, z, tilt, c = j[i]
        phi, theta = math.pi + tilt, c  # 180 deg - B with B = -tilt
        s2r = np.array(
            [math.sin(phi) * math.cos(theta), math.sin(phi) * math.sin(theta), math.cos(phi)]
        )
        tip = np.array([x, y, z + P]) + (P + W) * s2r
        np.testing.assert_allclose(p[i], tip, atol=1e-14 * 10, rtol=0)
        np.testing.assert_allclose(d[i], -s2r, atol=1e-15 * 10, rtol=0)  # tip -> pivot


def maxkins_forward(joints, P, W):
    """LinuxCNC maxkins_math.h forward (conventional_directions = 1), rewritten: (x, y) of
    the joints turned by C about the origin, minus (P + W) sin B in x; z = Z - (P + W)
    cos B + P."""
    x, y, z, b, c = joints
    r, theta = math.hypot(x, y), math.atan2(y, x) + c
    return np.array(
        [
            r * math.cos(theta) - (P + W) * math.sin(b),
            r * math.sin(theta),
            z - (P + W) * math.cos(b) + P,
        ]
    )


def maxkins_inverse(world, b, c, P, W):
    """LinuxCNC maxkins_math.h inverse (conventional_directions = 1), rewritten."""
    wx, wy, wz = world
    r, theta = math.hypot(wx, wy), math.atan2(wy, wx) - c
    return np.array(
        [
            r * math.cos(theta) + (P + W) * math.sin(b),
            r * math.sin(theta),
            wz + (P + W) * math.cos(b) - P,
        ]
    )


def test_table_head_matches_linuxcnc_maxkins_where_maxkins_is_consistent():
    """maxkins (tilting head B, C table) equals our table-head BC machine with head_pivot
    (0, 0, P), spindle_offset (0, 0, -P) where C = 0 (every B) and where B = 0 (every C).
    Where both are non-zero maxkins turns the joints' (x, y) by C but not the head's
    (P + W) sin B offset, so its forward and inverse are not each other's inverse there
    (shown below); ours turns the whole tool tip with the table and round-trips."""
    P, W = 0.1, 0.05
    machine = FiveAxisMachine(
        "table-head", "BC", tool_length=W, head_pivot=(0, 0, P), spindle_offset=(0, 0, -P)
    )
    j = _joints(300)
    for column in (3, 4):  # C = 0, then B = 0
        jj = j.copy()
        jj[:, 7 - column] = 0.0
        p, _ = machine.fk(jj)
        for i in range(len(jj)):
            np.testing.assert_allclose(p[i], maxkins_forward(jj[i], P, W), atol=1e-14 * 10)
    gaps = [
        np.abs(maxkins_inverse(maxkins_forward(row, P, W), row[3], row[4], P, W) - row[:3]).max()
        for row in j[:50]
    ]
    assert max(gaps) > 1e-3  # maxkins' own round trip fails where B and C are both turned
    p, d = machine.fk(j)
    np.testing.assert_allclose(machine.ik(p, d, j), j, atol=1e-12)


# -- the singular pose and the C-axis wrap -----------------------------------------------


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: f"{c[0]}-{c[1]}")
@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_tool_axis_along_c_is_singular_finite_and_holds_c(machines, config, backend):
    compiled, reference = machines[config]
    machine = compiled if backend == "compiled" else reference
    p = np.array([[0.1, -0.05, 0.02]] * 4)
    d = np.array([[0.0, 0.0, 1.0], [1e-13, -2e-13, 1.0], [0.0, 0.0, 3.0], [0.0, 0.0, -1.0]])
    prev = np.array([[0.0, 0.0, 0.0, 0.2, 1.234]] * 4)
    j, valid, status = machine.ik(p, d, prev, errors="nan", return_status=True)
    assert valid.all() and np.all(status == st.SINGULAR) and np.all(np.isfinite(j))
    np.testing.assert_array_equal(j[:, 4], 1.234)  # C held at the previous value
    both, ok, status_all = machine.ik_all(p, d, prev, return_status=True)
    assert ok.all() and np.all(np.isfinite(both)) and np.all(status_all == st.SINGULAR)
    p2, d2 = compiled.fk(j)
    np.testing.assert_allclose(p2, p, atol=1e-12)
    np.testing.assert_allclose(d2, d / np.linalg.norm(d, axis=1, keepdims=True), atol=1e-12)
    j = machine.ik(p[0], d[0], prev[0])  # raise mode: a singular pose is an answer
    assert np.isfinite(j).all()
    # fk reports it too, with finite outputs
    q = np.array([[0.1, 0.2, 0.3, 0.0, 0.7], [0.1, 0.2, 0.3, math.pi, 0.7]])
    pf, df, okf, sf = machine.fk(q, errors="nan", return_status=True)
    assert okf.all() and np.all(sf == st.SINGULAR) and np.isfinite(pf).all()


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: f"{c[0]}-{c[1]}")
def test_a_path_circling_the_c_axis_gives_a_continuous_c(machines, config):
    """Tool axes at 30 deg from the C axis, their azimuth turning three times round: with
    the previous joints passed along, C runs on over 6 pi without a jump (and the branch
    never flips); from zeros each point's C would stay in (-pi, pi] and jump."""
    compiled, reference = machines[config]
    azimuth = np.linspace(0.0, 6 * math.pi, 721)
    tilt = math.radians(30)
    d = np.column_stack(
        [
            math.sin(tilt) * np.cos(azimuth),
            math.sin(tilt) * np.sin(azimuth),
            np.full_like(azimuth, math.cos(tilt)),
        ]
    )
    p = np.column_stack([0.05 * np.cos(azimuth), 0.05 * np.sin(azimuth), np.zeros_like(azimuth)])
    for machine in (compiled, reference):
        j = machine.ik_path(p, d, [0.0, 0.0, 0.0, tilt, 0.0])
        step = np.abs(np.diff(j[:, 4]))
        assert step.max() < 0.05, step.max()  # 6 pi / 720 = 0.026 per step
        np.testing.assert_allclose(abs(j[-1, 4] - j[0, 4]), 6 * math.pi, atol=1e-9)
        assert np.ptp(np.sign(np.sin(j[:, 3]))) == 0  # one branch all along
        p2, d2 = compiled.fk(j)
        np.testing.assert_allclose(p2, p, atol=1e-12)
        np.testing.assert_allclose(d2, d, atol=1e-12)
    independent = compiled.ik(p, d)  # each from zeros
    assert np.abs(np.diff(independent[:, 4])).max() > 3.0


def test_a_path_through_the_singular_pose_holds_c_and_stays_finite(machines):
    compiled, _ = machines["head-head", "AC"]
    t = np.linspace(-0.3, 0.3, 61)  # the tilt passes 0: the tool axis along C at the middle
    d = np.column_stack([np.zeros_like(t), -np.sin(t), np.cos(t)])
    p = np.zeros((61, 3))
    j = compiled.ik_path(p, d, [0.0, 0.0, 0.0, -0.3, 0.5])
    assert np.isfinite(j).all()
    _, _, status = compiled.ik(p[30], d[30], j[29], errors="nan", return_status=True)
    assert status == st.SINGULAR
    p2, d2 = compiled.fk(j)
    np.testing.assert_allclose(d2, d, atol=1e-12)
    np.testing.assert_allclose(p2, p, atol=1e-12)


# -- bad input ------------------------------------------------------------------------------


def test_bad_inputs_raise_clear_errors_or_give_nan_rows(machines):
    compiled, reference = machines["table-head", "AC"]
    for machine in (compiled, reference):
        with pytest.raises(InputError, match="NaN or infinite values in rows"):
            machine.fk([[0, 0, 0, 0, 0], [0, 0, math.nan, 0, 0]])
        p, d, valid = machine.fk([[0, 0, 0, 0.1, 0], [math.inf, 0, 0, 0.1, 0]], errors="nan")
        assert valid.tolist() == [True, False] and np.isnan(p[1]).all() and np.isnan(d[1]).all()
        with pytest.raises(InputError, match="zero length"):
            machine.ik([0.1, 0, 0], [0, 0, 0])
        j, valid = machine.ik([[0.1, 0, 0]] * 2, [[0, 0, 0], [0, 0.2, 1]], errors="nan")
        assert valid.tolist() == [False, True] and np.isnan(j[0]).all()
        j, valid = machine.ik([0.1, 0, 0], [1e300, -1e300, 1e300], errors="nan")  # scaled
        assert valid and np.isfinite(j).all()
        with pytest.raises(InputError, match="not finite"):
            machine.ik([1.7e308, 1.7e308, 0], [1.0, -1.0, 1.0], [0, 0, 0, 0, 0])  # overflows
        with pytest.raises(InputError, match="shape"):
            machine.fk([0.0, 0.0, 0.0])
        with pytest.raises(InputError):
            machine.ik([0.1, 0, 0], [0, 0, 1], errors="maybe")


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(layout="gantry", rotary="AC"), "layout must be one of"),
        (dict(layout="head-head", rotary="AB"), "rotary must be AC"),
        (dict(layout="head-head", rotary="AC", c_pivot=(0.1, 0, 0)), "c_pivot has no effect"),
        (dict(layout="table-head", rotary="BC", tilt_pivot=(0, 0, 0.1)), "tilt_pivot has no"),
        (
            dict(layout="table-table", rotary="AC", tool_length=math.nan),
            "tool_length must be finite",
        ),
        (dict(layout="table-table", rotary="AC", head_pivot=(0, 0)), "head_pivot must hold 3"),
        (dict(layout="table-table", rotary="AC", name="1bad"), "invalid machine name"),
    ],
)
def test_bad_descriptions_are_geometry_errors(kwargs, message):
    with pytest.raises(GeometryError, match=message):
        MachineDescription(**kwargs)


def test_machine_files(tmp_path, repo_root):
    assert set(bundled_machines()) >= {"xyzac_trt", "xyzbc_trt", "bridge_bc_head", "table_head_bc"}
    m = FiveAxisMachine.load("xyzac_trt", backend="reference")
    assert m.description.layout == "table-table" and m.description.rotary == "AC"
    bad = tmp_path / "bad.toml"
    bad.write_text('[machine]\nlayout = "table-table"\nrotary = "AC"\nspeed = 3\n')
    with pytest.raises(GeometryError, match="unknown keys in \\[machine\\]: \\['speed'\\]"):
        FiveAxisMachine.from_toml(bad)
    bad.write_text('[machine]\nlayout = "table-table"\n')
    with pytest.raises(GeometryError, match="missing keys"):
        FiveAxisMachine.from_toml(bad)
    with pytest.raises(GeometryError, match="no bundled machine"):
        FiveAxisMachine.load("puma560")


def test_threaded_batches_give_the_single_threaded_bits():
    machine = FiveAxisMachine.load("table_head_bc")
    j = _joints(50_000)
    one = FiveAxisMachine.load("table_head_bc", threads=1)
    machine.threads = 2
    p, d = machine.fk(j)
    p1, d1 = one.fk(j)
    assert np.array_equal(p, p1) and np.array_equal(d, d1)
    assert np.array_equal(machine.ik_all(p, d, j)[0], one.ik_all(p, d, j)[0])


def test_cli_ik_of_a_file_is_a_path_and_reads_fk_output(tmp_path, capsys):
    """`deltagen fk` writes px..dz; `deltagen ik` reads them back as a path: C continuous
    over three turns, the joints those fk started from."""
    from deltagen.cli import main

    turn = np.linspace(0.0, 6 * math.pi, 181)
    j = np.column_stack(
        [0.02 * np.cos(turn), 0.01 * np.sin(turn), 0.05 + 0 * turn, 0.5 + 0 * turn, turn]
    )
    header = "x,y,z,a,c"
    np.savetxt(tmp_path / "j.csv", j, delimiter=",", header=header, comments="")
    assert (
        main(
            [
                "fk",
                "xyzac_trt",
                "--input",
                str(tmp_path / "j.csv"),
                "--output",
                str(tmp_path / "p.csv"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "ik",
                "xyzac_trt",
                "--input",
                str(tmp_path / "p.csv"),
                "--output",
                str(tmp_path / "j2.csv"),
                "--q0",
                "0,0,0,0.5,0",
            ]
        )
        == 0
    )
    back = np.genfromtxt(tmp_path / "j2.csv", delimiter=",", names=True)
    got = np.column_stack([back[n] for n in ("x", "y", "z", "a", "c")])
    np.testing.assert_allclose(got, j, atol=1e-12)
    assert main(["ik", "xyzac_trt", "0", "0", "0", "0", "0", "0"]) == 1  # zero tool axis
    assert "zero tool axis" in capsys.readouterr().err
    assert main(["fk", "xyzac_trt", "0", "0", "0"]) == 2
    assert main(["ik", "xyzac_trt", "0", "0", "0", "0", "0", "1", "--config", "up"]) == 2


@pytest.mark.parametrize("backend", ["compiled", "reference"])
def test_the_tilt_travel_keeps_the_branch_within_it(backend):
    """A head whose tilt travels over [-0.1, 2.0] rad: of a target reached with tilt 1.0
    only branch 1 is valid, and ik takes it even when the previous joints lie on the other
    branch; with the travel [0.2, 0.5] neither branch reaches it: UNREACHABLE."""
    from deltagen import UnreachableError

    geometry = dict(tool_length=0.05, head_pivot=(0.0, 0.01, 0.1), spindle_offset=(0, 0, -0.1))
    machine = FiveAxisMachine(
        "head-head", "AC", tilt_limits=(-0.1, 2.0), backend=backend, **geometry
    )
    free = FiveAxisMachine("head-head", "AC", backend=backend, **geometry)
    j = np.array([0.1, 0.2, 0.3, 1.0, 0.4])
    p, d = machine.fk(j)
    other = free.ik_all(p, d, j)[0][1]  # the same tool pose from branch 2 (tilt -1)
    np.testing.assert_allclose(other[3], -1.0, atol=1e-12)
    np.testing.assert_allclose(free.ik(p, d, other), other, atol=1e-12)  # no travel limit
    both, valid = machine.ik_all(p, d, j)
    assert valid.tolist() == [True, False] and np.isnan(both[1]).all()
    np.testing.assert_allclose(machine.ik(p, d, other), j, atol=1e-12)  # branch 1 only
    p, d = np.array([p, p]), np.array([d, d])
    narrow = FiveAxisMachine("head-head", "AC", tilt_limits=(0.2, 0.5), backend=backend, **geometry)
    with pytest.raises(UnreachableError, match="beyond its travel"):
        narrow.ik(p[0], d[0])
    q, ok, status = narrow.ik(p, d, errors="nan", return_status=True)
    assert not ok.any() and np.isnan(q).all() and np.all(status == st.UNREACHABLE)
    both, valid = narrow.ik_all(p, d)
    assert not valid.any() and np.isnan(both).all()


def test_tilt_limits_in_a_machine_file(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(
        '[machine]\nlayout = "table-table"\nrotary = "AC"\ntilt_limits_deg = [-120, 30]\n'
    )
    desc = MachineDescription.from_toml(path)
    np.testing.assert_allclose(desc.tilt_limits, np.radians([-120, 30]))
    for bad, message in (
        ("[30, -120]", "lower < upper"),
        ("[0, 200]", "lower < upper"),
        ("[1]", "list of 2"),
    ):
        path.write_text(
            f'[machine]\nlayout = "table-table"\nrotary = "AC"\ntilt_limits_deg = {bad}\n'
        )
        with pytest.raises(GeometryError, match=message):
            MachineDescription.from_toml(path)
