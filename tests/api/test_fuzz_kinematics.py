"""Fuzzing the kinematics methods: arbitrary shapes (0-d to 3-d batches, empty
batches), dtypes, memory layouts, magnitudes (1e+-300, subnormals, -0.0) and NaN / inf
placements go into DeltaRobot and SerialRobot. The property: the compiled backend either

* returns a result equal to the reference backend's (an independent numpy implementation)
  where both call a row valid, valid rows finite, invalid rows NaN, the same validity except
  on rows with huge inputs (where the two implementations may overflow in different
  intermediates), and errors="raise" raises a deltagen error exactly when a row is invalid;
* or raises a deltagen error (a subclass of deltagen.errors.DeltagenError) that names the
  argument -- never another exception, a crash, or a non-finite value marked valid.

Derandomised (tests/conftest.py loads the "ci" profile) with a bounded number of examples.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from delta_oracles import rod_condition
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deltagen import DeltaRobot
from deltagen.errors import DeltagenError

EXAMPLES = 300
FUZZ = settings(
    derandomize=True,
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

SPECIAL = [
    0.0,
    -0.0,
    5e-324,
    -2.5e-310,
    1e-300,
    1e155,
    -1e155,
    1e300,
    -1e300,
    1.7e308,
    math.nan,
    math.inf,
    -math.inf,
]
HUGE = 1e100  # rows with an input this large may overflow in one backend only


def _values(low, high):
    """Mostly ordinary values in [low, high], sometimes a special one."""
    return st.one_of(
        st.floats(low, high, allow_nan=False),
        st.floats(low, high, allow_nan=False),
        st.floats(low, high, allow_nan=False),
        st.sampled_from(SPECIAL),
    )


@st.composite
def lead_shapes(draw):
    """Leading batch dimensions: () (one point) up to 3 dimensions, empty ones included."""
    ndim = draw(st.integers(0, 3))
    return tuple(draw(st.integers(0, 3)) for _ in range(ndim))


LAYOUTS = ("C", "F", "reversed", "strided", "list")
DTYPES = ("float64", "float32", "int64", "object", "bool", "complex")


@st.composite
def arrays(draw, shape, low, high):
    """(value as handed to the API, float64 values it stands for, or None if the call must
    be refused) for an array of ``shape``."""
    dtype = draw(st.sampled_from(DTYPES) if draw(st.integers(0, 3)) == 0 else st.just("float64"))
    size = int(np.prod(shape))
    if dtype == "int64":
        base = np.array(draw(st.lists(st.integers(-3, 3), min_size=size, max_size=size)))
    else:
        base = np.array(draw(st.lists(_values(low, high), min_size=size, max_size=size)))
    base = base.astype(float).reshape(shape)
    layout = draw(st.sampled_from(LAYOUTS))
    if dtype == "float32":
        with np.errstate(over="ignore"):
            base = base.astype(np.float32).astype(float)  # what float32 can hold
    if dtype == "bool":
        value, refused = base != 0, True
    elif dtype == "complex":
        value, refused = base.astype(complex), True
    elif dtype == "object":
        value = base.astype(object)
        refused = draw(st.booleans()) and size > 0
        if refused:
            value.flat[draw(st.integers(0, size - 1))] = draw(
                st.sampled_from(["1.0", None, True, 1j])
            )
    else:
        value, refused = base.astype(dtype), False
    if layout == "F":
        value = np.asfortranarray(value)
    elif layout == "reversed" and value.ndim:
        value = np.ascontiguousarray(value[::-1])[::-1]  # negative strides, same values
    elif layout == "strided" and value.ndim:
        holder = np.zeros(value.shape[:-1] + (2 * value.shape[-1],), dtype=value.dtype)
        holder[..., ::2] = value
        value = holder[..., ::2]
    elif layout == "list" and dtype in ("float64", "int64"):
        value = value.tolist()
    return value, base, refused


def _rows(a, lead):
    """a (lead + trailing) as (rows, values per row), empty batches included."""
    a = np.asarray(a)
    return a.reshape(int(np.prod(lead)), int(np.prod(a.shape[len(lead) :])))


def _is_deltagen_error(exc, names):
    assert isinstance(exc, DeltagenError), f"{type(exc).__name__}: {exc}"
    text = str(exc)
    assert text, "empty error message"
    assert any(n in text for n in names) or "row" in text or "shape" in text, text


def _huge_rows(lead, *bases):
    """Rows (flattened lead) with an input beyond HUGE in magnitude."""
    n = int(np.prod(lead))
    out = np.zeros(n, dtype=bool)
    for b in bases:
        flat = np.abs(_rows(np.broadcast_to(b, lead + b.shape[-1:]), lead))
        with np.errstate(invalid="ignore"):
            out |= np.any(flat > HUGE, axis=1)
    return out


def _compare(name, got, want, lead, huge, atol_of, angle_columns=(), compare_huge=True):
    """The property for one errors="nan" call on both backends."""
    *outs_c, valid_c = got
    *outs_r, valid_r = want
    n = int(np.prod(lead))
    valid_c = np.asarray(valid_c)
    assert valid_c.shape == lead and valid_c.dtype == bool, (name, valid_c.shape, lead)
    vc, vr = valid_c.reshape(n), np.asarray(valid_r).reshape(n)
    differ = vc != vr
    assert not np.any(differ & ~huge), f"{name}: validity differs in rows {np.flatnonzero(differ)}"
    both = vc & vr if compare_huge else vc & vr & ~huge
    for oc, orf in zip(outs_c, outs_r):
        oc, orf = np.asarray(oc), np.asarray(orf)
        assert oc.shape[: len(lead)] == lead and oc.shape == orf.shape, (name, oc.shape)
        assert oc.dtype == np.float64
        fc = _rows(oc, lead)
        assert np.all(np.isfinite(fc[vc])), f"{name}: a non-finite value marked valid"
        assert np.all(np.isnan(fc[~vc])), f"{name}: an invalid row that is not NaN"
        if both.any():
            fr = _rows(orf, lead)
            diff = fc[both] - fr[both]
            for c in angle_columns:  # angles agree modulo 2 pi (atan2 at +-pi, -0.0)
                diff[:, c] = (diff[:, c] + np.pi) % (2 * np.pi) - np.pi
            err = np.max(np.abs(diff), axis=1)
            with np.errstate(over="ignore"):  # the tolerance of huge rows is inf
                atol = atol_of(both, np.max(np.abs(fr[both]), axis=1))
            bad = err > atol
            assert not bad.any(), (
                f"{name}: backends differ by {err[bad].max():.3g} > {atol[bad].min():.3g}"
            )


def _call(method, *args, names):
    """errors="nan" then errors="raise": the result, or None after a checked refusal."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no RuntimeWarning may reach the user
            result = method(*args, errors="nan")
    except Exception as exc:  # the property: only deltagen errors, naming the problem
        _is_deltagen_error(exc, names)
        return None, exc
    valid = np.asarray(result[-1])
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            raised = method(*args)
    except Exception as exc:
        _is_deltagen_error(exc, names)
        assert not valid.all(), f"raised although every row is valid: {exc}"
    else:
        assert valid.all(), "errors='raise' returned although a row is invalid"
        raised = raised if isinstance(raised, tuple) else (raised,)
        for a, b in zip(raised, result[:-1]):
            np.testing.assert_array_equal(a, b)
    return result, None


# ------------------------------------------------------------------------------ delta

DELTA_METHODS = {
    "fk": (("q",), (-3.5, 3.5)),
    "fk_vel": (("q", "qd"), (-3.5, 3.5)),
    "fk_acc": (("q", "qd", "qdd"), (-3.5, 3.5)),
    "jacobian": (("q",), (-3.5, 3.5)),
    "ik": (("p",), (-1.2, 1.2)),
    "ik_vel": (("p", "pd"), (-1.2, 1.2)),
    "ik_acc": (("p", "pd", "pdd"), (-1.2, 1.2)),
}


@pytest.fixture(scope="module")
def delta_pair():
    return DeltaRobot.default(), DeltaRobot.default(backend="reference")


@st.composite
def delta_calls(draw):
    method = draw(st.sampled_from(sorted(DELTA_METHODS)))
    names, (low, high) = DELTA_METHODS[method]
    lead = draw(lead_shapes())
    width = draw(st.sampled_from([3, 4]))
    if method == "jacobian":
        width = 3 if draw(st.booleans()) else 4
    args = []
    for k, _ in enumerate(names):
        # the positions of ik-level calls sit below the base, around the workspace
        lo, hi = (low, high) if k or method[:2] != "ik" else (-0.6, 0.6)
        shape = lead if k == 0 or draw(st.booleans()) else lead[1:]  # broadcasting
        args.append(draw(arrays(shape + (width,), lo, hi)))
        if k == 0 and method[:2] == "ik":
            value, base, refused = args[0]
            if isinstance(value, np.ndarray) and value.dtype.kind == "f" and value.size:
                value = np.array(value)  # a copy: move z below the base
                value[..., 2] -= 0.8
                base = base.copy()
                base[..., 2] -= 0.8
                args[0] = (value, base, refused)
    return method, names, lead, width, args


@FUZZ
@given(call=delta_calls())
def test_fuzz_delta(delta_pair, call):
    compiled, reference = delta_pair
    method, names, lead, width, args = call
    values = [a[0] for a in args]
    refused = any(a[2] for a in args)
    got, exc = _call(getattr(compiled, method), *values, names=names)
    want, exc_r = _call(getattr(reference, method), *values, names=names)
    if refused:
        assert exc is not None and exc_r is not None, "a bad dtype was accepted"
        return
    assert (exc is None) == (exc_r is None), (exc, exc_r)
    if exc is not None:
        assert type(exc) is type(exc_r)
        return
    bases = [a[1] for a in args]
    huge = _huge_rows(lead, *bases)
    size = compiled.geometry.size
    # scale: the rates' magnitude; kappa: the rod matrix's condition number (ill-conditioned
    # rows lose accuracy in both backends alike)
    n = int(np.prod(lead))
    rates = [_rows(np.broadcast_to(b, lead + b.shape[-1:]), lead) for b in bases[1:]]
    scale = np.ones(n)
    for r in rates:
        with np.errstate(invalid="ignore"):
            scale = np.maximum(scale, np.nanmax(np.abs(np.nan_to_num(r)), axis=1, initial=1.0))
    q_flat = np.broadcast_to(bases[0], lead + (width,)).reshape(n, width)
    if method[:2] == "ik":
        q_ref, _ = reference.ik(q_flat, errors="nan")
        p_ref = q_flat
        q_ref = np.asarray(q_ref).reshape(n, width)
    else:
        q_ref = q_flat
        p_ref = np.asarray(reference.fk(q_flat, errors="nan")[0]).reshape(n, width)
    with np.errstate(all="ignore"):
        kappa = rod_condition(compiled.geometry, q_ref[:, :3], p_ref[:, :3])
    kappa = np.where(np.isfinite(kappa), kappa, 1e300)

    def atol_of(rows, magnitude):
        factor = np.maximum(1.0, kappa[rows] / 100.0) ** (2 if method.endswith("acc") else 1)
        return 1e-12 * np.maximum(size, magnitude) * scale[rows] ** 2 * factor

    _compare(method, got, want, lead, huge, atol_of)


ANGLE_COLUMNS = {"euler": (0, 1, 2), "rpy": (0, 1, 2), "pose": (3, 4, 5)}


# ----------------------------------------------------------------------------- serial

SERIAL_METHODS = {
    "fk": ("q",),
    "frames": ("q",),
    "jacobian": ("q",),
    "jacobian_dot": ("q", "qd"),
    "euler": ("q",),
    "rpy": ("q",),
    "pose": ("q",),
    "manipulability": ("q",),
    "analytic_jacobian": ("q",),
    "ik_all": ("T",),
}
ARMS = ("puma560", "lecture_prp", "lecture_scara", "bosch_sr800")


@pytest.fixture(scope="module")
def arms(serial_arms):
    return {name: (serial_arms(name), serial_arms(name, "reference")) for name in ARMS}


@st.composite
def serial_calls(draw):
    arm = draw(st.sampled_from(ARMS))
    method = draw(st.sampled_from(sorted(SERIAL_METHODS)))
    if method == "ik_all" and arm not in ("puma560", "lecture_scara"):
        method = "fk"
    lead = draw(lead_shapes())
    return arm, method, lead, draw(st.randoms(use_true_random=False))


def _serial_args(arm, method, lead, rnd, draw_array):
    n = arm.n
    if method == "ik_all":
        q = np.array([rnd.uniform(-2.5, 2.5) for _ in range(int(np.prod(lead)) * n)])
        T = arm.fk(q.reshape(lead + (n,)), errors="nan")[0].copy()
        flat = T.reshape(-1, 16)
        for row in flat:  # perturb some poses: huge, tiny, non-finite, not rigid
            if rnd.random() < 0.3:
                row[rnd.randrange(16)] = rnd.choice(SPECIAL)
        return [(T, T, False)]
    args = [draw_array(lead + (n,))]
    if method == "jacobian_dot":
        args.append(draw_array((lead if rnd.random() < 0.5 else lead[1:]) + (n,)))
    return args


@FUZZ
@given(call=serial_calls(), data=st.data())
def test_fuzz_serial(arms, call, data):
    name, method, lead, rnd = call
    compiled, reference = arms[name]
    names = SERIAL_METHODS[method]
    args = _serial_args(
        compiled, method, lead, rnd, lambda shape: data.draw(arrays(shape, -3.5, 3.5))
    )
    values = [a[0] for a in args]
    refused = any(a[2] for a in args)
    if method == "ik_all":
        try:
            got = compiled.ik_all(*values)
            want = reference.ik_all(*values)
        except Exception as exc:
            _is_deltagen_error(exc, names)
            return
        q_c, v_c = got
        q_r, v_r = want
        assert v_c.shape == lead + v_c.shape[-1:]
        assert np.all(np.isfinite(q_c[v_c])), "a non-finite branch marked valid"
        # the branches found agree where both call them valid (both reproduce the pose)
        both = v_c & v_r
        diff = q_c[both] - q_r[both]
        revolute = [j.revolute for j in compiled.description.joints]
        diff[:, revolute] = (diff[:, revolute] + np.pi) % (2 * np.pi) - np.pi  # +-pi alike
        np.testing.assert_allclose(diff, 0.0, rtol=0, atol=1e-7)
        return
    got, exc = _call(getattr(compiled, method), *values, names=names)
    want, exc_r = _call(getattr(reference, method), *values, names=names)
    if refused:
        assert exc is not None and exc_r is not None, "a bad dtype was accepted"
        return
    assert (exc is None) == (exc_r is None), (exc, exc_r)
    if exc is not None:
        assert type(exc) is type(exc_r)
        return
    bases = [a[1] for a in args]
    huge = _huge_rows(lead, *bases)
    n = int(np.prod(lead))
    prismatic = ~np.array([j.revolute for j in compiled.description.joints])
    stroke = np.ones(n)
    rate = np.ones(n)
    with np.errstate(invalid="ignore"):
        q_flat = _rows(np.broadcast_to(bases[0], lead + (compiled.n,)), lead)
        stroke = np.maximum(1.0, np.nanmax(np.abs(q_flat[:, prismatic]), axis=1, initial=1.0))
        if len(bases) > 1:
            qd_flat = _rows(np.broadcast_to(bases[1], lead + (compiled.n,)), lead)
            rate = np.maximum(1.0, np.nanmax(np.abs(np.nan_to_num(qd_flat)), axis=1, initial=1.0))
    size = 2.0

    def atol_of(rows, magnitude):
        # manipulability multiplies up to six singular values, each carrying the stroke
        power = 6 if method == "manipulability" else 2
        return 1e-12 * np.maximum(size, magnitude) * (stroke[rows] ** power) * rate[rows]

    # values of rows with huge inputs are not compared: a joint offset added to a revolute
    # angle beyond 2^53 is lost in the reference (cos(q + offset) of the rounded sum) but
    # not in the C (cos q, sin q and the offset's exact cos and sin); valid rows are still
    # finite, and invalid ones NaN
    _compare(
        method, got, want, lead, huge, atol_of, ANGLE_COLUMNS.get(method, ()), compare_huge=False
    )
