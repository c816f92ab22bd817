"""Workspace and dexterity: deltagen.api.workspace against independent evidence.

* the delta's usable volume (ik over a voxel grid, compiled core) against a Monte-Carlo
  integral over joint space by fk (numpy reference): V = int |det J(q)| dq over the crank
  angles whose platform point is usable (change of variables, one q per point on the
  elbow-out branch), within its statistical error plus the voxel discretisation;
* the inscribed cylinder and box lie inside the usable set (random points on and in them,
  checked by an independent usable test on the reference backend), and neither a slab one
  height step beyond either end nor a 1 % larger radius is usable everywhere;
* a serial arm's reach against the sum of its link lengths.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from deltagen import DeltaRobot, InputError, SerialRobot

LO, HI, CMAX = -math.pi / 2, math.pi / 2, 10.0


@pytest.fixture(scope="module")
def robot():
    return DeltaRobot.default()


@pytest.fixture(scope="module")
def ref(robot):
    return robot.with_backend("reference")


@pytest.fixture(scope="module")
def ws(robot):
    return robot.workspace(0.03)


def _usable(ref, p):
    """The three conditions, written again with numpy's SVD on the reference backend."""
    p = np.asarray(p, dtype=float).reshape(-1, 3)
    q, ok = ref.ik(p, errors="nan")
    back, ok_fk = ref.fk(np.where(ok[:, None], q, 0.0), errors="nan")
    ok &= ok_fk & (np.linalg.norm(back - p, axis=1) < 1e-9)
    ok &= np.all((q >= LO) & (q <= HI), axis=1)
    J, ok_j = ref.jacobian(np.where(ok[:, None], q, 0.0), errors="nan")
    ok &= ok_j
    sv = np.linalg.svd(np.where(ok[:, None, None], J, np.eye(3)), compute_uv=False)
    return ok & (sv[:, 0] / sv[:, 2] <= CMAX)


def test_delta_volume_matches_a_monte_carlo_integral_over_joint_space(ws, ref):
    rng = np.random.default_rng(1)
    n = 100_000
    q = rng.uniform(LO, HI, (n, 3))
    p, ok = ref.fk(q, errors="nan")
    q_back, ok_ik = ref.ik(np.where(ok[:, None], p, 0.0), errors="nan")
    ok &= ok_ik & (np.max(np.abs(q_back - q), axis=1) < 1e-7)  # the elbow-out branch
    J, ok_j = ref.jacobian(q, errors="nan")
    ok &= ok_j
    Jok = np.where(ok[:, None, None], J, np.eye(3))
    sv = np.linalg.svd(Jok, compute_uv=False)
    ok &= sv[:, 0] / sv[:, 2] <= CMAX
    w = np.where(ok, np.abs(np.linalg.det(Jok)), 0.0)
    box = (HI - LO) ** 3
    v_mc, sigma = box * w.mean(), box * w.std() / math.sqrt(n)
    assert v_mc > 0.1
    # 4 sigma of the Monte-Carlo estimate + 1 % for the voxel grid (step 3 cm)
    assert abs(ws.volume - v_mc) <= 4 * sigma + 0.01 * v_mc, (ws.volume, v_mc, sigma)


def test_delta_height_range_and_maps(ws):
    zlo, zhi = ws.z_range
    assert zlo < zhi < 0.0  # the platform works below the base
    u = ws.usable
    assert np.all(ws.condition[u] <= CMAX) and np.all(ws.condition[u] >= 1.0)
    assert np.all(ws.velocity_gain[u] > 0) and np.all(ws.force_gain[u] > 0)
    # force gain 1/sigma_min over velocity gain sigma_max is the condition number
    np.testing.assert_allclose(ws.force_gain[u] * ws.velocity_gain[u], ws.condition[u], rtol=1e-9)
    assert np.all(ws.q[u] >= LO) and np.all(ws.q[u] <= HI)


def _disk(rng, R, z, n):
    t = rng.uniform(0, 2 * np.pi, n)
    r = R * np.sqrt(rng.uniform(0, 1, n))
    return np.stack([r * np.cos(t), r * np.sin(t), np.full(n, z)], axis=-1)


def _square(rng, a, z, n):
    xy = rng.uniform(-a, a, (n, 2))
    return np.column_stack([xy, np.full(n, z)])


@pytest.mark.parametrize("kind", ["cylinder", "box"])
def test_inscribed_envelope_lies_inside_and_cannot_grow(ws, ref, kind):
    env = ws.cylinder if kind == "cylinder" else ws.box
    assert env is not None and env.size > 0.1 and env.height > 0.1
    rng = np.random.default_rng(7)
    n = 20_000
    R = env.size
    t = rng.uniform(0, 2 * np.pi, n)
    z = rng.uniform(env.z_min, env.z_max, n)
    if kind == "cylinder":
        surface = np.stack([R * np.cos(t), R * np.sin(t), z], axis=-1)
        inside = np.stack([_disk(rng, R, zz, 1)[0] for zz in z[:4000]])
        cap = _disk
    else:
        side = rng.integers(0, 4, n)
        u = rng.uniform(-R, R, n)
        x = np.where(side == 0, R, np.where(side == 1, -R, u))
        y = np.where(side == 2, R, np.where(side == 3, -R, u))
        surface = np.stack([x, y, z], axis=-1)
        inside = np.stack([_square(rng, R, zz, 1)[0] for zz in z[:4000]])
        cap = _square
    caps = np.concatenate([cap(rng, R, env.z_min, 4000), cap(rng, R, env.z_max, 4000)])
    for pts in (surface, inside, caps):
        assert _usable(ref, pts).all()
    # one height step beyond either end: somewhere not usable
    for z_out in (env.z_max + env.dz, env.z_min - env.dz):
        assert not _usable(ref, cap(rng, R, z_out, 20_000)).all()
    # a 1 % larger body: somewhere on its side not usable
    ang = np.linspace(0, 2 * np.pi, 1440, endpoint=False)
    zs = np.concatenate([np.linspace(env.z_min, env.z_max, 60), [env.z_min, env.z_max]])
    big = 1.01 * R
    if kind == "cylinder":
        ring = np.stack([big * np.cos(ang), big * np.sin(ang)], axis=-1)
    else:
        s = big / np.maximum(np.abs(np.cos(ang)), np.abs(np.sin(ang)))
        ring = np.stack([s * np.cos(ang), s * np.sin(ang)], axis=-1)
    grown = np.concatenate([np.column_stack([ring, np.full(len(ring), zz)]) for zz in zs])
    assert not _usable(ref, grown).all()


def test_peak_torque_map_needs_inertia_and_grows_with_acceleration(robot):
    from deltagen.errors import GeometryError

    with pytest.raises(GeometryError, match="inertia"):
        robot.with_inertia(None).workspace(0.1, acceleration=10.0, envelope=False)
    from deltagen import DeltaInertia

    heavy = robot.with_inertia(DeltaInertia.default())
    slow = heavy.workspace(0.08, acceleration=1.0, envelope=False)
    fast = heavy.workspace(0.08, acceleration=50.0, envelope=False)
    u = slow.usable
    assert u.any() and np.all(np.isfinite(slow.peak_torque[u]))
    assert np.all(fast.peak_torque[u] > slow.peak_torque[u])
    # at rest with a = 1 m/s^2 the torque is close to the gravity torque: check one voxel
    i = tuple(np.argwhere(u)[0])
    p = np.array([slow.x[i[0]], slow.y[i[1]], slow.z[i[2]]])
    worst = 0.0
    for k in range(3):
        for sgn in (1, -1):
            a = np.zeros(3)
            a[k] = sgn * 1.0
            worst = max(
                worst, np.abs(heavy.inverse_dynamics_from_platform(p, np.zeros(3), a)).max()
            )
    assert slow.peak_torque[i] == pytest.approx(worst, rel=1e-12)


def test_bad_workspace_options_raise(robot):
    with pytest.raises(InputError, match="step"):
        robot.workspace(-1.0)
    with pytest.raises(InputError, match="q_limits"):
        robot.workspace(0.1, q_limits=(1.0, 0.0))
    with pytest.raises(InputError, match="max_condition"):
        robot.workspace(0.1, max_condition=0.5)


def test_serial_reach_is_the_sum_of_link_lengths():
    arm = SerialRobot.from_dh(
        [{"a": 0.0, "alpha": math.pi / 2}, {"a": 0.5}, {"a": 0.3}], "standard", name="elbow3"
    )
    step = 0.02
    ws = arm.workspace(step, samples=100_000)
    reach = 0.5 + 0.3
    # voxel centres: within half a voxel diagonal of the reach sphere, and close to it
    assert reach - 1.5 * step <= ws.reach <= reach + math.sqrt(3) / 2 * step
    # no reachable voxel lies wholly inside the hole of radius 0.5 - 0.3 about the shoulder
    X, Y, Z = np.meshgrid(ws.x, ws.y, ws.z, indexing="ij")
    d = np.sqrt(X**2 + Y**2 + Z**2)
    assert not np.any(ws.reachable & (d < 0.2 - math.sqrt(3) / 2 * step))
    # stretched arm (q3 = 0) is singular: its tool points are among the singular points
    assert ws.singular_points.shape[1] == 3


def test_serial_workspace_with_orientation_reaches_what_fk_reaches():
    arm = SerialRobot.load("puma560")
    down = np.diag([1.0, -1.0, -1.0])
    ws = arm.workspace(0.15, orientation=down, samples=20_000)
    assert ws.reachable.any()
    # every reachable voxel centre: fk of an ik solution puts the tool there, pointing down
    pts, _ = ws.points()
    T = np.broadcast_to(np.eye(4), (len(pts), 4, 4)).copy()
    T[:, :3, :3] = down
    T[:, :3, 3] = pts
    q, ok = arm.ik(T, errors="nan", singular="allow")
    assert ok.all()
    np.testing.assert_allclose(arm.fk(q)[:, :3, 3], pts, atol=1e-9)


# -- pictures and the 3D page (deltagen.apps.workspace) ---------------------------------

CHROMIUM = "/usr/bin/chromium"
RECORDER = """<script>
window.__errors = [];
window.addEventListener("error", function (e) { window.__errors.push("error: " + e.message); });
window.addEventListener("unhandledrejection", function (e) {
  window.__errors.push("rejection: " + e.reason); });
(function () { var orig = console.error; console.error = function () {
  window.__errors.push("console.error: " + Array.prototype.join.call(arguments, " "));
  return orig.apply(console, arguments); }; })();
window.addEventListener("load", function () { setTimeout(function () {
  var d = document.createElement("pre"); d.id = "deltagen-report";
  d.textContent = "ERRORS=" + JSON.stringify(window.__errors) +
    " PLOTS=" + document.querySelectorAll(".js-plotly-plot .main-svg").length;
  document.body.appendChild(d); }, 500); });
</script>"""


def _chromium(page, tmp_path, screenshot=None):
    """Load a page in headless Chromium with an error recorder injected first in <head>
    (and take its screenshot in the same run when asked); returns (errors list, number of
    plotly SVG layers, stderr)."""
    import json
    import re
    import subprocess

    text = page.read_text()
    probe = tmp_path / ("probe_" + page.name)
    probe.write_text(text.replace("<head>", "<head>" + RECORDER, 1))
    base = [
        CHROMIUM,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--enable-unsafe-swiftshader",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        f"--user-data-dir={tmp_path / 'chromium-profile'}",
        "--virtual-time-budget=15000",
        "--window-size=1000,700",
    ]
    # one browser start: the DOM (with the recorder's report) and the screenshot of the same
    # load (the page as drawn, plus the report's one line of text)
    shot = [] if screenshot is None else [f"--screenshot={screenshot}"]
    run = subprocess.run(
        base + ["--dump-dom", *shot, probe.as_uri()], capture_output=True, text=True, timeout=180
    )
    found = re.search(r"ERRORS=(\[.*?\]) PLOTS=(\d+)", run.stdout)
    assert found, f"no report from the page; chromium stderr:\n{run.stderr[-2000:]}"
    return json.loads(found.group(1)), int(found.group(2)), run.stderr


@pytest.fixture(scope="module")
def pictures(robot, tmp_path_factory):
    pytest.importorskip("matplotlib")
    pytest.importorskip("plotly")
    from deltagen.apps import workspace as app

    out = tmp_path_factory.mktemp("workspace")
    ws = robot.workspace(0.05)
    return (
        out,
        ws,
        (
            app.write_slices(ws, out / "slices.png"),
            app.write_page(robot, ws, out / "page.html", title="test"),
            app.write_summary(ws, out / "summary.csv", robot),
        ),
    )


def test_pictures_are_written_and_not_empty(pictures):
    out, ws, (png, html, summary) = pictures
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    text = html.read_text()
    assert html.stat().st_size > 1_000_000  # plotly.js inlined
    # self-contained: no script or stylesheet fetched from the network
    import re

    assert not re.search(r"<script[^>]+src=|<link[^>]+href=\"http", text)
    rows = summary.read_text().splitlines()
    assert rows[0].startswith("# deltagen ") and "volume_m3" in summary.read_text()


def test_delta_skeleton_has_rods_of_length_l_b(robot):
    from deltagen.apps.workspace import delta_skeleton

    q = np.array([0.3, -0.2, 0.5])
    s = delta_skeleton(robot, q)
    pieces = np.split(s, np.flatnonzero(np.isnan(s[:, 0])))
    chains = [c[~np.isnan(c[:, 0])] for c in pieces[1:4]]
    g = robot.geometry
    for A, B, C in chains:
        assert np.linalg.norm(B - A) == pytest.approx(g.l_a, rel=1e-12)
        assert np.linalg.norm(C - B) == pytest.approx(g.l_b, rel=1e-9)


@pytest.mark.slow  # two browser starts (the page with its screenshot, the bad page)
def test_the_page_loads_in_headless_chromium_without_errors(pictures, tmp_path):
    import os

    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} is absent (make sysdeps installs Chromium where apt works)")
    out, ws, (png, html, summary) = pictures
    shot = tmp_path / "page.png"
    errors, plots, _ = _chromium(html, tmp_path, screenshot=shot)
    assert errors == []
    assert plots >= 1  # plotly drew the figure
    assert shot.exists() and shot.stat().st_size > 10_000
    # the recorder can fail: a page with a script error is caught
    bad = tmp_path / "bad.html"
    bad.write_text("<html><head></head><body><script>no_such_function();</script></body></html>")
    errors, _, _ = _chromium(bad, tmp_path)
    assert errors and "no_such_function" in errors[0]


def test_cli_workspace_writes_its_files(tmp_path):
    pytest.importorskip("matplotlib")
    pytest.importorskip("plotly")
    from deltagen.cli import main

    code = main(["workspace", "default", "--out", str(tmp_path), "--step", "0.1", "--quiet"])
    assert code == 0
    for name in ("workspace_slices.png", "workspace.html", "workspace_summary.csv"):
        assert (tmp_path / name).stat().st_size > 0
