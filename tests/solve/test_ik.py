"""The IK planner (deltagen/solve/ik.py) that SerialRobot builds once per arm, the shared base
of the robot families (deltagen/api/base.py) and the import graph of api/ and solve/.

The method table below is stated from each bundled arm's structure (model/structure.py and
the robot files): a closed form where the structure has one (the planar SCARAs, the
gantries, the elbow manipulators with a central wrist, the UR's parallel triple), the
general 6R solver for a 6R chain without one (the Puma with an offset wrist), and the
numeric solver for the rest (a 7-joint arm, a PRP chain).
"""

from __future__ import annotations

import ast
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from helpers import REPO

from deltagen import DeltaRobot, FiveAxisMachine, LinearDelta, SerialRobot, Tripod
from deltagen.api.coupled import CoupledArm
from deltagen.api.serial import IKSolutions, bundled_robots, bundled_urdfs
from deltagen.errors import IncompleteSolutionsWarning, UnreachableError
from deltagen.paths import robots_dir
from deltagen.solve import ik as ik_planner
from deltagen.solve.ik import IKPlanner, IKResult

PACKAGE = REPO / "deltagen"

# arm -> (ik_all's path for method="auto", ik's auto method is the closed form's branches)
CLOSED = ("closed_form", True)
METHODS = {
    "bosch_sr800": CLOSED,  # planar SCARA
    "lecture_scara": CLOSED,
    "manutec_h5": CLOSED,
    "scara_sr800": CLOSED,
    "gantry_xyz_ac": CLOSED,  # three prismatic axes, then the wrist
    "gantry_xyz_wrist": CLOSED,
    "palletiser_xyzc": CLOSED,
    "manutec_r15": CLOSED,  # elbow manipulators with a central wrist
    "miskolc_rrrr": CLOSED,
    "motoman_up6": CLOSED,
    "puma560": CLOSED,
    "ur5": CLOSED,  # three parallel axes (the UR family)
    "puma560_offset_wrist": ("complete", True),  # 6R without a closed form
    "lecture_prp": (None, False),  # neither a closed form nor 6R: numeric
    "panda": (None, False),  # 7 joints: numeric
}


@pytest.fixture(scope="module")
def arms():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IncompleteSolutionsWarning)
        return {name: SerialRobot.load(name, "reference") for name in METHODS}


def test_the_table_covers_every_bundled_arm():
    assert set(METHODS) == set(bundled_robots() + bundled_urdfs())


@pytest.mark.parametrize("name", sorted(METHODS))
def test_method_choice_of_the_bundled_arms(arms, name):
    arm = arms[name]
    planner = arm.ik_planner
    path, analytic = METHODS[name]
    assert isinstance(planner, IKPlanner) and planner.arm is arm
    assert planner.all_method("auto") == path
    # ik's "auto": the closed form's (or the combined method's) named branches, else numeric
    assert planner.choose("auto", None, {})[0] is analytic
    assert bool(arm.analytic_configs()) is analytic
    # explicit methods are taken as asked
    for method in ("closed_form", "complete", "combined"):
        assert planner.all_method(method) == method


def test_capabilities_are_attributes_made_once(arms):
    planner = arms["puma560"].ik_planner
    assert planner.analytic is planner.analytic  # cached on first use
    assert planner.general is planner.general
    assert math.isfinite(planner.reach) and planner.reach > 0
    assert planner.z_only is None  # a 6R arm tilts its tool
    scara = arms["lecture_scara"].ik_planner
    assert scara.z_only is not None  # a SCARA turns its tool about z only
    assert scara.partial_mask  # 4 joints: the numeric solver's mask leaves components out
    # the arm's _general_6r (read and forced by tests) is the planner's attribute
    arm = arms["puma560_offset_wrist"]
    assert arm._general_6r is arm.ik_planner.general


def test_planner_answers_as_the_arm(arms):
    """ik_all through the planner is SerialRobot.ik_all's answer; ik's batch path returns one
    IKResult whose q reaches the targets (fk round trip) where valid."""
    arm = arms["puma560"]
    lo, hi = arm.qlim.T
    q = lo + (hi - lo) * np.random.default_rng(3).uniform(0.2, 0.8, (12, 6))  # within limits
    T = arm.fk(q)
    a, b = arm.ik_all(T), arm.ik_planner.ik_all(T)
    assert isinstance(a, IKSolutions) and a.complete and b.complete
    np.testing.assert_array_equal(a.valid, b.valid)
    np.testing.assert_array_equal(a.q[a.valid], b.q[b.valid])
    lead, flat, finite, rigid = ik_planner.check_poses(T)
    result = arm.ik_planner.solve(flat, rigid, None, True, None, "allow", {}, True)
    assert isinstance(result, IKResult) and result.complete
    assert result.cause is None and result.valid.all()
    np.testing.assert_allclose(arm.fk(result.q), T, atol=1e-9)


def test_an_unsolved_row_gets_its_cause(arms):
    """A target beyond the reach: IKResult.cause is the UnreachableError ik raises."""
    arm = arms["puma560"]
    T = arm.fk(np.zeros(6))[None].copy()
    T[0, :3, 3] = [10.0, 0.0, 0.0]  # metres: far beyond the Puma's reach
    lead, flat, finite, rigid = ik_planner.check_poses(T)
    result = arm.ik_planner.solve(flat, rigid, None, True, None, "raise", {}, True)
    assert not result.valid.any() and np.isnan(result.q).all()
    assert isinstance(result.cause, UnreachableError)
    with pytest.raises(UnreachableError) as raised:
        arm.ik(T)
    assert str(raised.value) == str(result.cause)
    quiet = arm.ik_planner.solve(flat, rigid, None, True, None, "raise", {}, False)
    assert quiet.cause is None  # errors="nan" does not word the causes


def test_incomplete_warning_names_the_caller(arms):
    """The IncompleteSolutionsWarning points at the line that called ik_all (stacklevel)."""
    arm = SerialRobot.load("puma560_offset_wrist", "reference")
    T = arm.fk(np.zeros(6))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        arm.ik_all(T, method="combined")
    found = [w for w in caught if issubclass(w.category, IncompleteSolutionsWarning)]
    assert found and Path(found[0].filename).resolve() == Path(__file__).resolve()


# -- the base of the robot families ------------------------------------------------------


@pytest.mark.parametrize(
    "family, model",
    [
        (DeltaRobot, "default_delta.toml"),
        (SerialRobot, "puma560.toml"),
        (LinearDelta, None),
        (Tripod, None),
    ],
)
def test_families_share_construction(family, model):
    """from_toml / default / with_backend of the base keep the model and the threads."""
    robot = (
        family.from_toml(robots_dir() / model, "reference", threads=2)
        if model
        else family.default("reference", threads=2)
    )
    assert isinstance(robot, family) and robot.backend == "reference" and robot.threads == 2
    other = robot.with_backend("reference")
    assert type(other) is family and other.threads == 2
    attr = type(robot)._model_attr
    assert getattr(other, attr) is getattr(robot, attr)


def test_reference_core_calls_the_reference_with_the_model():
    from deltagen.reference import five_axis as reference

    machine = FiveAxisMachine("table-table", "AC", backend="reference")
    j = np.array([[0.1, -0.2, 0.3, 0.4, -0.5]])
    p, d, status = machine._core.fk(j)
    p2, d2, status2 = reference.fk(machine.description, j)
    np.testing.assert_array_equal(p, p2)
    np.testing.assert_array_equal(d, d2)
    np.testing.assert_array_equal(status, status2)


def test_from_urdf_decides_plain_or_coupled():
    """One loader: a chain without mimic joints is a SerialRobot, one with them a
    CoupledArm; CoupledArm.from_urdf always wraps (identity coupling)."""
    plain = SerialRobot.from_urdf(robots_dir() / "ur5.urdf", backend="reference")
    assert type(plain) is SerialRobot
    wrapped = CoupledArm.from_urdf(robots_dir() / "ur5.urdf", backend="reference")
    assert type(wrapped) is CoupledArm and type(wrapped.full) is SerialRobot
    assert wrapped.n == plain.n


# -- no import circle --------------------------------------------------------------------


def _graph(packages):
    """module -> the deltagen modules it imports (anywhere in the file, lazy imports too,
    but not under ``if TYPE_CHECKING:``, which never runs)."""
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    graph = {}
    for name, path in modules.items():
        if not any(name.startswith(f"deltagen.{p}") for p in packages):
            continue
        tree = ast.parse(path.read_text())
        skip = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                skip.update(id(n) for n in ast.walk(node))
        targets = set()
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            if isinstance(node, ast.ImportFrom) and node.module and not node.level:
                for alias in node.names:
                    full = f"{node.module}.{alias.name}"
                    targets.add(full if full in modules else node.module)
            elif isinstance(node, ast.Import):
                targets.update(a.name for a in node.names)
        graph[name] = {t for t in targets if t in modules and t != name}
    return graph


def _cycles(graph):
    """Every module that lies on a cycle of the graph (Tarjan's strongly connected
    components of more than one module)."""
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_api_and_solve_import_no_circle():
    assert _cycles(_graph(("api", "solve"))) == []


def test_the_cycle_check_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
