"""Every option and spec value validated: a bad sweep-spec value is a SweepError naming its
key (one schema, api/sweep.py _SCHEMA), never an IndexError, TypeError or AttributeError;
--workers must be positive; the envelope search refuses too few heights and says NaN when
it did not run; numpy scalars count as numbers wherever Python numbers do (bools never);
the environment variables share one message style; masked arrays are refused; the peak
torque map's acceleration is a finite value >= 0."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from deltagen import DeltaInertia, DeltaRobot, InputError, SerialRobot, cli, inputs
from deltagen.api.sweep import SweepError, SweepSpec

BASE = {
    "design": "sobol",
    "n": 4,
    "seed": 3,
    "ranges": {"r_a": [0.15, 0.25], "r_b": 0.045, "l_a": [0.3, 0.4], "l_b": [0.7, 0.9]},
    "score": {"step": 0.12, "envelope_levels": 8},
}
INERTIA = {"I_a": 0.01, "m_a": 0.3, "r_ca": 0.1, "m_b": 0.1, "m_p": 0.5}
MOVE = {"from": [-0.2, 0.0, -0.8], "to": [0.2, 0.0, -0.8], "duration": 0.25}


def _with(path, value):
    """BASE with the key at ``path`` ("score.max_condition") set to ``value``."""
    spec = {k: (dict(v) if isinstance(v, dict) else v) for k, v in BASE.items()}
    *tables, key = path.split(".")
    table = spec
    for name in tables:
        table = table.setdefault(name, {})
    table[key] = value
    return spec


@pytest.mark.parametrize(
    "path, value, named",
    [
        ("score.q_limits_deg", [90], "score.q_limits_deg"),
        ("score.q_limits_deg", [90, -90], "score.q_limits_deg"),
        ("score.q_limits_deg", ["a", 90], "score.q_limits_deg[0]"),
        ("score.max_condition", "ten", "score.max_condition"),
        ("score.max_condition", 0.5, "score.max_condition"),
        ("score.step", -0.1, "score.step"),
        ("score.step", math.nan, "score.step"),
        ("score.step", True, "score.step"),
        ("score.envelope_levels", 3, "score.envelope_levels"),
        ("score.envelope_levels", 8.5, "score.envelope_levels"),
        ("score.colour", 1, "score: unknown keys"),
        ("score", "fast", "score must be a table"),
        ("move", "abc", "move must be a table"),
        ("move", {"from": [0, 0, -0.8], "duration": 1.0}, "move needs to"),
        ("move", {**MOVE, "duration": 0}, "move.duration"),
        ("move", {**MOVE, "payload": -1}, "move.payload"),
        ("move", {**MOVE, "to": [0, 0]}, "move.to"),
        ("move", {**MOVE, "speed": 2}, "move: unknown keys"),
        ("n", 2.5, "n must be an integer"),
        ("n", True, "n must be an integer"),
        ("seed", -1, "seed must be an integer >= 0"),
        ("design", 3, "design must be"),
        ("theta_deg", [0, 120], "theta_deg must be 3 numbers"),
        ("theta_deg", [0, 120, "x"], "theta_deg[2]"),
        ("ranges.r_a", [0.3, 0.2], "ranges.r_a must have low <= high"),
        ("ranges.r_a", "big", "ranges.r_a"),
        ("ranges", [1, 2], "ranges must be a table"),
        ("constraints", {"worst_condition": {"max": "8"}}, "constraints.worst_condition.max"),
        ("constraints", {"worst_condition": {"most": 8}}, "constraints.worst_condition"),
        ("constraints", "none", "constraints must be a table"),
    ],
)
def test_a_bad_spec_value_is_a_sweep_error_naming_its_key(path, value, named):
    spec = _with(path, value)
    if path == "move":
        spec["inertia"] = INERTIA
    with pytest.raises(SweepError) as info:
        SweepSpec.from_mapping(spec, source="spec.toml")
    assert named in str(info.value), str(info.value)
    assert str(info.value).startswith("spec.toml")


JUNK = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=5),
    st.lists(st.one_of(st.integers(-5, 5), st.floats(-1e3, 1e3), st.text(max_size=2)), max_size=4),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)
KEYS = [
    "design",
    "n",
    "seed",
    "theta_deg",
    "ranges.r_a",
    "score.step",
    "score.max_condition",
    "score.q_limits_deg",
    "score.envelope_levels",
    "move.from",
    "move.duration",
    "move.payload",
    "constraints.worst_condition",
]


@settings(max_examples=100)
@given(key=st.sampled_from(KEYS), value=JUNK)
def test_any_spec_value_is_accepted_or_a_sweep_error(key, value):
    spec = _with(key, value)
    if key.startswith("move"):
        spec["move"] = {**MOVE, key.split(".")[1]: value}
        spec["inertia"] = INERTIA
    try:
        checked = SweepSpec.from_mapping(spec, source="spec.toml")
    except SweepError as exc:
        text = str(exc)
        # the key, its table, or (a huge length: a huge grid) the memory budget
        assert key.split(".")[-1] in text or "table" in text or "of memory" in text, text
        return
    # accepted: the normalised values are numbers of the documented kinds
    assert checked.n >= 1 and isinstance(checked.n, int)
    for low, high in checked.ranges.values():
        assert math.isfinite(low) and math.isfinite(high) and low <= high
    step = checked.score.get("step")
    assert step is None or (math.isfinite(step) and step > 0)


def test_cli_sweep_bad_values_and_workers_exit_2(tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    good = (
        'design = "sobol"\nn = 2\n[ranges]\nr_a = 0.2\nr_b = 0.045\nl_a = 0.35\nl_b = 0.8\n'
        "[score]\nstep = 0.12\n"
    )
    for line, named in (
        ("q_limits_deg = [90]", "score.q_limits_deg"),
        ('max_condition = "ten"', "score.max_condition"),
    ):
        spec.write_text(good + line + "\n")
        code = cli.main(["sweep", str(spec), "--scheduler", "inprocess", "--out", str(tmp_path)])
        err = capsys.readouterr().err
        assert code == 2 and named in err and "Traceback" not in err
    spec.write_text('move = "abc"\n' + good)
    assert cli.main(["sweep", str(spec), "--out", str(tmp_path)]) == 2
    assert "move must be a table" in capsys.readouterr().err
    spec.write_text(good)
    for workers in ("-1", "0"):
        code = cli.main(["sweep", str(spec), "--workers", workers, "--out", str(tmp_path)])
        err = capsys.readouterr().err
        assert code == 2 and f"workers must be an integer >= 1, got {workers}" in err
    assert not (tmp_path / "sweep.csv").exists()


# ------------------------------------------------------------------------ the workspace


@pytest.fixture(scope="module")
def delta():
    return DeltaRobot.default(backend="reference")


def test_envelope_needs_four_heights_and_is_nan_when_not_searched(delta):
    for levels in (1, 2, 3):
        with pytest.raises(InputError, match="envelope_levels must be an integer >= 4"):
            delta.workspace(0.1, envelope_levels=levels, progress=False)
    with pytest.raises(InputError, match="envelope_levels"):
        delta.workspace(0.1, envelope_levels=4.0, progress=False)
    skipped = delta.workspace(0.1, envelope=False, progress=False).summary()
    assert math.isnan(skipped["cylinder_radius_m"]) and math.isnan(skipped["box_height_m"])
    assert skipped["volume_m3"] > 0
    searched = delta.workspace(0.1, envelope_levels=6, progress=False).summary()
    assert searched["cylinder_radius_m"] > 0 and searched["cylinder_height_m"] > 0


@pytest.mark.parametrize("bad", [-1.0, math.nan, math.inf, "9.81", True])
def test_peak_torque_acceleration_must_be_finite_and_not_negative(delta, bad):
    heavy = delta.with_inertia(DeltaInertia.default())
    with pytest.raises(InputError, match="acceleration"):
        heavy.workspace(0.1, acceleration=bad, envelope=False, progress=False)
    with pytest.raises(InputError, match="payload"):
        heavy.workspace(0.1, acceleration=1.0, payload=-0.5, envelope=False, progress=False)


# ----------------------------------------------------------------------- numpy scalars


def test_numpy_scalars_are_numbers_where_python_numbers_are(delta):
    a = delta.workspace(0.12, max_condition=12.0, envelope_levels=6, progress=False)
    b = delta.workspace(
        np.float64(0.12),
        max_condition=np.float32(12.0),
        envelope_levels=np.int64(6),
        progress=False,
    )
    assert np.array_equal(a.usable, b.usable) and a.cylinder == b.cylinder
    c = delta.workspace(np.float32(0.125), envelope=False, progress=False)
    assert c.x.size == delta.workspace(float(np.float32(0.125)), envelope=False).x.size
    robot = DeltaRobot.default(backend="reference", threads=np.int64(2))
    assert robot.threads == 2
    arm = SerialRobot.load("puma560", backend="reference")
    w1 = arm.workspace(0.2, samples=3000, progress=False)
    w2 = arm.workspace(np.float32(0.2), samples=np.int64(3000), progress=False)
    assert np.array_equal(w1.reachable.shape, w2.reachable.shape)
    spec = SweepSpec.from_mapping(
        {**BASE, "n": np.int64(4), "seed": np.uint8(3), "score": {"step": np.float32(0.12)}}
    )
    assert spec.n == 4 and spec.seed == 3 and spec.designs().shape == (4, 4)
    assert json.loads(json.dumps(spec.raw))["n"] == 4  # the CSV header's spec line
    for bad in (True, np.bool_(True)):
        with pytest.raises(InputError):
            DeltaRobot.default(backend="reference", threads=bad)
        with pytest.raises(InputError):
            delta.workspace(bad, progress=False)


# ----------------------------------------------------------------- environment variables


@pytest.mark.parametrize("value", ["abc", "0", "-1", "1.5", " "])
@pytest.mark.parametrize("name", ["DELTAGEN_BUILD_JOBS", "DELTAGEN_THREADS"])
def test_integer_environment_variables_share_one_message(monkeypatch, name, value):
    from deltagen.native.build import _build_jobs
    from deltagen.native.parallel import resolve_threads

    read = _build_jobs if name == "DELTAGEN_BUILD_JOBS" else lambda: resolve_threads(None)
    monkeypatch.setenv(name, value)
    if value.strip() == "":
        assert read() >= 1  # empty: as unset
        return
    with pytest.raises(InputError) as info:
        read()
    assert str(info.value).startswith(f"{name} must be a positive integer (")
    assert f"got {value!r}; unset it to use every available core" in str(info.value)


def test_build_jobs_caps_the_cores(monkeypatch):
    from deltagen.native.build import _build_jobs

    monkeypatch.setenv("DELTAGEN_BUILD_JOBS", "1")
    assert _build_jobs() == 1
    monkeypatch.setenv("DELTAGEN_BUILD_JOBS", " +1 ")
    assert _build_jobs() == 1
    assert inputs.env_positive_int("DELTAGEN_UNSET_FOR_TEST", "x", "y") is None


@pytest.mark.parametrize(
    "value, expected",
    [("0", False), ("false", False), ("OFF", False), (" No ", False), ("1", True)]
    + [("TRUE", True), ("yes", True), ("On", True), ("", True)],
)
def test_flags_read_the_usual_words(monkeypatch, value, expected):
    monkeypatch.setenv("DELTAGEN_LEAN_EXT", value)
    assert inputs.env_flag("DELTAGEN_LEAN_EXT", True, "x") is expected


@pytest.mark.parametrize("name", ["DELTAGEN_LEAN_EXT", "DELTAGEN_NATIVE", "DELTAGEN_BENCH_ORACLES"])
def test_a_flag_that_is_no_flag_is_refused(monkeypatch, name):
    monkeypatch.setenv(name, "maybe")
    with pytest.raises(
        InputError, match=f"{name} must be one of 1, true, yes, on, 0, false, no, off"
    ):
        inputs.env_flag(name, True, "x")


def test_lean_extension_is_off_for_any_off_word(monkeypatch):
    from deltagen.native import lean

    for word in ("FALSE", "off", "No"):
        monkeypatch.setenv("DELTAGEN_LEAN_EXT", word)
        assert lean.extension() is None
    monkeypatch.setenv("DELTAGEN_LEAN_EXT", "nope")
    with pytest.raises(InputError, match="DELTAGEN_LEAN_EXT"):
        lean.extension()


# ---------------------------------------------------------------------- masked arrays


def test_masked_arrays_are_refused_not_silently_unmasked(delta):
    q = np.ma.array([[0.1, 0.2, 0.3], [9.0, 9.0, 9.0]], mask=[[0, 0, 0], [1, 1, 1]])
    with pytest.raises(InputError, match=r"q is a masked array.*filled\(np.nan\)"):
        delta.fk(q)
    # the documented way: masked rows become NaN rows, which are invalid
    p, ok = delta.fk(q.filled(np.nan), errors="nan")
    assert ok.tolist() == [True, False]
    arm = SerialRobot.load("puma560", backend="reference")
    with pytest.raises(InputError, match="masked array"):
        arm.fk(np.ma.array(np.zeros(6), mask=[0, 0, 0, 0, 0, 1]))
