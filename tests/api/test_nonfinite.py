"""The finite-output rule (deltagen/status.py): finite but huge inputs whose results
overflow are never OK / valid, in both backends, for every quantity; errors="nan" gives NaN
and False there, errors="raise" a deltagen error naming the cause.

The evidence that a result cannot be finite is computed independently of the kernels:
from the linearity of the quantity in the huge input (fk in prismatic joint values, rates in
qd, Jdot in qd), evaluated at unit size and scaled in exact arithmetic, or from a bound
(|q_delta| <= pi, so a target 1e155 m away has no finite crank solution).
"""

from __future__ import annotations

import math
import re
from fractions import Fraction

import numpy as np
import pytest

from deltagen import DeltaRobot
from deltagen.api.serial import SerialRobot
from deltagen.derive.functions import AllFinite
from deltagen.errors import DeltagenError
from deltagen.reference import delta as ref_delta
from deltagen.reference import serial as ref_serial
from deltagen.status import INVALID, OK

BACKENDS = ("compiled", "reference")
BIG = float(np.finfo(float).max)


def _exceeds(values, scale) -> np.ndarray:
    """Per row: does some value * scale (exact) exceed the largest double? values (N, ...)."""
    flat = np.asarray(values, dtype=float).reshape(len(values), -1)
    limit = Fraction(BIG)
    return np.array([any(abs(Fraction(v) * Fraction(scale)) > limit for v in row) for row in flat])


def _assert_invalid_everywhere(result, rows):
    """errors="nan" result tuple: every output NaN and valid False on ``rows``; every other
    row finite and valid."""
    *outs, valid = result
    valid = np.asarray(valid).reshape(-1)
    assert not valid[rows].any()
    for out in outs:
        flat = np.asarray(out).reshape(valid.shape[0], -1)
        assert np.isnan(flat[rows]).all()
        assert np.isfinite(flat[valid]).all()


# ------------------------------------------------------------------------------ delta


@pytest.mark.parametrize("backend", BACKENDS)
def test_delta_ik_of_a_target_far_away_is_invalid(backend):
    robot = DeltaRobot.default(backend=backend)
    p = np.array([[1e155, 0.0, -1e155], [0.0, 0.0, -0.8], [-1e300, 1e300, 1e-300]])
    q, valid = robot.ik(p, errors="nan")
    # |q| <= pi for every reachable target; a target 1e155 m away is out of reach
    assert valid.tolist() == [False, True, False]
    assert np.isnan(q[[0, 2]]).all() and np.isfinite(q[1]).all()
    with pytest.raises(DeltagenError, match=r"rows \[0\]"):
        robot.ik(p[0])
    with pytest.raises(DeltagenError):
        robot.ik(p)
    for name, args in (
        ("ik_vel", (p, np.zeros(3))),
        ("ik_acc", (p, np.zeros(3), np.zeros(3))),
    ):
        _assert_invalid_everywhere(getattr(robot, name)(*args, errors="nan"), [0, 2])


def test_delta_kernel_statuses_are_invalid_not_ok():
    """The raw kernels (C core and numpy reference) say INVALID, with NaN everywhere."""
    robot = DeltaRobot.default()
    p = np.array([[1e155, 0.0, -1e155, 0.5]])
    for q, status in (robot._core.ik(p), ref_delta.ik(robot.geometry, p)):
        assert status.tolist() == [INVALID]
        assert np.isnan(q).all()


def _rate_rows(robot, count=2000, seed=1):
    """Crank angles of OK rows over the whole range and their Jacobians (reference)."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1.5, 2.0, (count, 3))
    J, status = ref_delta.jacobian(robot.geometry, q)
    keep = status == OK
    return q[keep], J[keep]


@pytest.mark.parametrize("backend", BACKENDS)
def test_delta_fk_vel_with_huge_rates(backend):
    """pd = J qd is linear in qd: with qd = 1.7e308 (1, -1, 1) it overflows exactly where
    J (1, -1, 1) exceeds 1.8e308 / 1.7e308 (near the workspace boundary)."""
    robot = DeltaRobot.default(backend=backend)
    q, J = _rate_rows(robot)
    direction = np.array([1.0, -1.0, 1.0])
    must_fail = _exceeds(J @ direction * 0.99, 1.7e308)  # a 1 % margin for rounding
    may_pass = ~_exceeds(J @ direction * 1.01, 1.7e308)
    assert must_fail.any() and may_pass.any()
    p, pd, valid = robot.fk_vel(q, 1.7e308 * direction, errors="nan")
    assert not valid[must_fail].any()
    assert valid[may_pass].all()
    assert np.isnan(pd[~valid]).all() and np.isnan(p[~valid]).all()
    assert np.isfinite(pd[valid]).all()
    with pytest.raises(DeltagenError, match="overflow"):
        robot.fk_vel(q, 1.7e308 * direction)


@pytest.mark.parametrize("backend", BACKENDS)
def test_delta_fk_acc_with_huge_rates(backend):
    """pdd has a term quadratic in qd: qd = 1e155 gives about 1e310 > 1.8e308 (the centripetal
    term |pd - Sd|^2 alone, l_a qd^2, is 0.35e310)."""
    robot = DeltaRobot.default(backend=backend)
    q, _ = _rate_rows(robot, 50)
    q = q[robot.jacobian(q, errors="nan")[-1]]
    qd = np.full(3, 1e155)
    result = robot.fk_acc(q, qd, np.zeros(3), errors="nan")
    _assert_invalid_everywhere(result, np.arange(len(q)))
    with pytest.raises(DeltagenError, match="overflow"):
        robot.fk_acc(q, qd, np.zeros(3))
    # the same rates at 1e-155 are fine (no underflow to a false failure)
    assert robot.fk_acc(q, qd * 1e-310, np.zeros(3), errors="nan")[-1].all()


@pytest.mark.parametrize("backend", BACKENDS)
def test_delta_ik_vel_and_ik_acc_with_huge_rates(backend):
    robot = DeltaRobot.default(backend=backend)
    p = np.array([[0.0, 0.0, -0.8], [0.1, -0.05, -0.9]])
    _assert_invalid_everywhere(robot.ik_vel(p, [1e308, -1e308, 1e308], errors="nan"), [0, 1])
    _assert_invalid_everywhere(
        robot.ik_acc(p, [1e155, -1e155, 1e155], [0.0, 0.0, 0.0], errors="nan"), [0, 1]
    )
    with pytest.raises(DeltagenError, match="overflow"):
        robot.ik_acc(p, [1e155, -1e155, 1e155], [0.0, 0.0, 0.0])


@pytest.mark.parametrize("backend", BACKENDS)
def test_delta_tiny_and_signed_zero_inputs_stay_valid(backend):
    """Subnormal and -0.0 inputs are ordinary numbers: valid, equal to the zero input's."""
    robot = DeltaRobot.default(backend=backend)
    tiny = np.array([[5e-324, -0.0, 1e-310], [-0.0, -0.0, -0.0]])
    p, valid = robot.fk(tiny, errors="nan")
    assert valid.all()
    np.testing.assert_allclose(p, robot.fk(np.zeros((2, 3))), rtol=0, atol=1e-15)


# ----------------------------------------------------------------------------- serial


def _arm(rows, name, backend):
    return SerialRobot.from_dh(rows, "standard", name=name, backend=backend)


# two prismatic joints along the base z axis, then a revolute one: z = q1 + q2
PP_R = [
    dict(joint="prismatic", a=0.0, alpha=0.0),
    dict(joint="prismatic", a=0.0, alpha=0.0),
    dict(joint="revolute", a=0.4, alpha=0.0, d=0.0),
]
# a Stanford-like R R P arm: the stroke q3 is the lever arm of both revolute joints
RRP = [
    dict(joint="revolute", a=0.0, alpha_deg=-90, d=0.3),
    dict(joint="revolute", a=0.0, alpha_deg=90, d=0.2),
    dict(joint="prismatic", a=0.0, alpha=0.0),
]


def _position_exceeds(arm, q):
    """Does the tool position of q (N, n) leave the doubles? It is affine in the prismatic
    joint values: p = p(0) + sum_k q_k (p(e_k) - p(0)) at the revolute values of q, each
    term evaluated at unit size by the reference and summed in exact arithmetic."""
    prismatic = [k for k, j in enumerate(arm.description.joints) if not j.revolute]
    out = []
    for row in q:
        base = row.copy()
        base[prismatic] = 0.0
        T0, _ = ref_serial.fk(arm.description, base[None])
        total = [Fraction(float(x)) for x in T0[0, :3, 3]]
        for k in prismatic:
            unit = base.copy()
            unit[k] = 1.0
            Tk, _ = ref_serial.fk(arm.description, unit[None])
            for c in range(3):
                total[c] += Fraction(float(row[k])) * (
                    Fraction(float(Tk[0, c, 3])) - Fraction(float(T0[0, c, 3]))
                )
        out.append(any(abs(t) > Fraction(BIG) for t in total))
    return np.array(out)


@pytest.mark.parametrize("backend", BACKENDS)
def test_serial_fk_whose_position_overflows(backend):
    arm = _arm(PP_R, "pp_r", backend)
    q = np.array(
        [[1.7e308, 1.7e308, 0.3], [1e300, 1e300, 0.3], [1.7e308, -1.7e308, 1.0], [1e308, 1e308, 2]]
    )
    exceeds = _position_exceeds(arm, q)
    assert exceeds.tolist() == [True, False, False, True]
    for name in ("fk", "frames", "euler", "rpy", "pose"):
        result = getattr(arm, name)(q, errors="nan")
        _assert_invalid_everywhere(result, np.flatnonzero(exceeds))
        with pytest.raises(DeltagenError, match="overflow"):
            getattr(arm, name)(q)
    T, _ = arm.fk(q[[1, 2]], errors="nan")  # the finite rows are right
    np.testing.assert_allclose(T[:, 2, 3], [2e300, 0.0], rtol=1e-15, atol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_serial_fk_of_huge_angles_is_valid(backend):
    """Huge revolute angles do not overflow (cos and sin stay in [-1, 1]): valid, and the
    two backends agree (both reduce the angle exactly)."""
    arm = SerialRobot.load("puma560", backend=backend)
    q = np.full((1, 6), 1e300)
    T, valid = arm.fk(q, errors="nan")
    assert valid.all()
    T_ref, status = ref_serial.fk(arm.description, q)
    assert status.tolist() == [OK]
    np.testing.assert_allclose(T, T_ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("frame", ["base", "tool"])
def test_serial_jacobian_dot_with_huge_rates(backend, frame):
    """Jdot is linear in qd: Jdot(q, 1e200 qd) = 1e200 Jdot(q, qd); with the stroke 1e300
    Jdot(q, qd) is about 1e300, so 1e200 times it cannot be a double."""
    arm = _arm(RRP, "rrp", backend)
    q = np.array([[0.3, -0.4, 1e300], [0.3, -0.4, 0.5]])
    qd = np.array([1.0, 1.0, 1.0])
    unit, unit_valid = arm.jacobian_dot(q, qd, frame=frame, errors="nan")
    assert unit_valid.all()
    exceeds = _exceeds(unit, 1e200)
    assert exceeds.tolist() == [True, False]
    _assert_invalid_everywhere(arm.jacobian_dot(q, 1e200 * qd, frame=frame, errors="nan"), [0])
    with pytest.raises(DeltagenError, match="overflow"):
        arm.jacobian_dot(q, 1e200 * qd, frame=frame)


@pytest.mark.parametrize("backend", BACKENDS)
def test_serial_derived_numbers_are_never_valid_and_infinite(backend):
    """manipulability of the RRP arm at a stroke of 1e300: two singular values near 1e300,
    their product is not a double; condition_number of two identical prismatic columns (the
    PP_R arm) is infinite (sigma_min = 0 exactly)."""
    arm = _arm(RRP, "rrp", backend)
    q = np.array([[0.3, -0.4, 1e300], [0.3, -0.4, 0.5]])
    J, valid = arm.jacobian(q, errors="nan")
    assert valid.all()
    sv = np.linalg.svd(J, compute_uv=False)
    assert _exceeds(sv[:, :1] / 1e300 * sv[:, 1:2], 1e300).tolist() == [True, False]
    m, m_valid = arm.manipulability(q, errors="nan")
    assert m_valid.tolist() == [False, True] and np.isnan(m[0]) and np.isfinite(m[1])
    with pytest.raises(DeltagenError, match="manipulability"):
        arm.manipulability(q)

    pp = _arm(PP_R, "pp_r", backend)
    c, c_valid = pp.condition_number([[0.0, 0.0, 0.3]], errors="nan")
    assert c_valid.tolist() == [False] and np.isnan(c).all()
    with pytest.raises(DeltagenError, match="condition number"):
        pp.condition_number([0.0, 0.0, 0.3])


@pytest.mark.parametrize("backend", BACKENDS)
def test_singularities_of_rows_without_a_report_raise(backend):
    """The singularity report of a NaN q used to say "not singular"."""
    arm = SerialRobot.load("puma560", backend=backend)
    with pytest.raises(DeltagenError, match=r"NaN or infinite values in rows \[1\]"):
        arm.singularities([[0.1] * 6, [0.1, math.nan, 0.0, 0.0, 0.0, 0.0]])
    pp = _arm(PP_R, "pp_r", backend)  # z = q1 + q2 overflows, and so does the Jacobian
    with pytest.raises(DeltagenError, match="overflow"):
        pp.singularities([1.7e308, 1.7e308, 0.3])
    assert not arm.singularities([0.1] * 6)["singular"]


def test_kernel_status_docs_state_the_rule():
    """The rule is written where C users read it: every function's status line and the
    header's status paragraph."""
    from deltagen import paths

    for header in paths.generated_dir().glob("*.h"):
        if header.name.endswith(".cdef.h"):
            continue
        # comment lines joined where codegen/layout.py wrapped them
        text = re.sub(r"\n\s*\*\s+", " ", header.read_text())
        assert "An OK row's outputs are all finite" in text
        # each function's status line, and the paragraph on the status codes
        assert text.count("status    out, n:") + 1 == text.count("arithmetic overflows")


def test_lowering_guards_any_kernel():
    """guard_outputs needs nothing from a kernel: a new kernel (here a made-up one with an
    output that is NaN by design where ``bad`` holds, one that is never NaN by design and a
    constant) gets the INVALID branch, and only the NaN its own Piecewise explains is
    exempt from the check."""
    import sympy as sp

    from deltagen.codegen.lowering import guard_outputs, lower
    from deltagen.derive.kernel import Kernel, Port, Stage

    x, y, a, b, c, bad = sp.symbols("x y a b c bad", real=True)
    kernel = Kernel(
        name="made_up",
        doc="",
        inputs=(Port("u", (x, y), "", "-", width=2),),
        outputs=(Port("v", (a, b, c), "", "-", width=3),),
        stages=(
            Stage(
                "",
                (
                    (bad, x < 0),
                    (a, sp.Piecewise((sp.nan, bad), (x * y, True))),
                    (b, x / y),
                    (c, sp.Piecewise((sp.nan, bad), (1, True))),
                ),
            ),
        ),
        status=sp.Piecewise((1, bad), (0, True)),
    )
    guarded = guard_outputs(kernel)
    (nonfinite, rule), *checked = guarded.stages[-1].assignments
    # the test reads the raw values (the Piecewise without its NaN branch), so that the
    # per-point loop vectorises; each checked output is one select
    assert rule == sp.Or(sp.And(sp.Not(bad), sp.Not(AllFinite(x * y))), sp.Not(AllFinite(b)))
    assert [str(s) for s, _ in checked] == ["a_checked", "b_checked", "c_checked"]
    assert dict(checked)[sp.Symbol("a_checked")] == sp.Piecewise(
        (sp.nan, sp.Or(bad, nonfinite)), (x * y, True)
    )
    assert guarded.status.args[0] == (INVALID, nonfinite)
    assert "nonfinite_output" in lower(kernel).status


def test_every_generated_function_has_the_check():
    """Every lowered kernel of every generated module guards its outputs, in each of its
    per-point loops (the delta kernels that store straight into the caller's rows have
    one loop for 3-axis rows and one for 4-axis rows; the delta's inverse kinematics two of
    each, before and after their atan2 loops)."""
    from deltagen import paths

    for source in paths.generated_dir().glob("*.c"):
        text = source.read_text()
        starts = [
            m.start()
            for m in re.finditer(
                r"^int deltagen_\w+\((size_t n|const deltagen_\w+_geometry)", text, re.M
            )
        ]
        assert starts, source.name
        for begin, end in zip(starts, [*starts[1:], len(text)]):
            function = text[begin:end]
            name = function[: function.index("(")]
            if "_ik_newton(size_t n" in function[:200]:
                continue
            if "_forward_dynamics(size_t n" in function[:200]:
                # forward dynamics wraps two lowered kernels and checks its own solution
                assert "finite &= isfinite(x[j]) != 0;" in text, source.name
                continue
            if name == "int deltagen_hexapod_fk":
                # the hexapod's fk wraps the runtime's damped Newton (deltagen_hexapod_fk.c),
                # which marks a point OK only when its iterate is finite and converged
                continue
            checks = function.count("const int nonfinite_output =")
            loops = function.count("/* loop: points */")
            assert checks >= 1, (source.name, name)
            if "/* loop: atan2 */" in function:
                # split at its atan2 loops (codegen/render.py atan2_loops): the guard is in
                # the finishing loop of each pair
                loops //= 2
            assert loops in (0, checks), (source.name, name, loops, checks)
