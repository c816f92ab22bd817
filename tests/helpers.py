"""Helpers shared by the test files of every stage folder (tests/<stage>/test_*.py).

Fixtures live in tests/conftest.py; plain functions and constants live here, imported as
``from helpers import ...`` (tests/conftest.py puts tests/ on sys.path under any
--import-mode, as it does for delta_oracles).
"""

from __future__ import annotations

import ctypes
import hashlib
import math
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import delta_oracles
import numpy as np
import pytest

from deltagen import SerialRobot
from deltagen.reference import serial as serial_reference

TESTS = Path(__file__).resolve().parent
REPO = TESTS.parent
ROBOTS = REPO / "robots"
BASELINES = TESTS / "baselines"

#: The C compiler the tests that build C drivers use (skipped where absent).
GCC = shutil.which("gcc")
needs_gcc = pytest.mark.skipif(GCC is None, reason="gcc not installed")

#: AddressSanitizer + UndefinedBehaviorSanitizer, every report fatal.
SANITIZE = [
    "-fsanitize=address,undefined",
    "-fno-sanitize-recover=all",
    "-fno-omit-frame-pointer",
    "-g",
]


def compile_c(
    sources,
    output: Path,
    *,
    flags=(),
    cwd: Path | None = None,
    sanitize: bool = False,
    libs=("-lm",),
) -> Path:
    """Build a C program (or, with -shared in ``flags``, a library) with gcc: warning-free
    (the compiler's text is the assertion message), skipped when the sanitizer runtime is
    not installed. Returns ``output``."""
    if GCC is None:
        pytest.skip("gcc not installed")
    cmd = [GCC, *flags, *(SANITIZE if sanitize else ()), *map(str, sources), "-o", str(output)]
    built = subprocess.run([*cmd, *libs], cwd=cwd, capture_output=True, text=True)
    if sanitize and built.returncode != 0 and "sanitize" in built.stderr:
        pytest.skip(f"no sanitizer runtime: {built.stderr[-300:]}")
    assert built.returncode == 0 and not built.stderr.strip(), built.stderr[-3000:]
    return Path(output)


def compiled_fit_angle(tmp_path: Path):
    """The runtime's hand-written deltagen_fit_angle (codegen/runtime/deltagen_limits.h),
    compiled by gcc into a shared library, as a numpy-broadcasting function."""
    from deltagen.paths import runtime_dir

    source = tmp_path / "fit.c"
    source.write_text(
        '#include "deltagen_limits.h"\n'
        "double fit(double a, double lo, double hi, double lo_tol, double hi_tol)\n"
        "{ return deltagen_fit_angle(a, lo, hi, lo_tol, hi_tol); }\n"
    )
    library = compile_c(
        [source],
        tmp_path / "fit.so",
        flags=["-std=c99", "-O2", "-shared", "-fPIC", f"-I{runtime_dir()}"],
    )
    fit = ctypes.CDLL(str(library)).fit
    fit.restype = ctypes.c_double
    fit.argtypes = [ctypes.c_double] * 5
    return np.vectorize(lambda *args: fit(*map(float, args)), otypes=[float])


def random_q(arm, rng, count, margin=0.0):
    """``count`` joint vectors uniform in the arm's limits (infinite limits: +-pi), kept
    ``margin`` inside them."""
    lo, hi = arm.qlim.T
    lo = np.where(np.isfinite(lo), lo, -np.pi)
    hi = np.where(np.isfinite(hi), hi, np.pi)
    return lo + margin + (hi - lo - 2 * margin) * rng.random((count, arm.n))


def in_limit_q(arm, rng, count):
    """``count`` joint vectors uniform in the arm's limits clipped to [-pi, pi]."""
    lim = arm.qlim
    lo, hi = np.maximum(lim[:, 0], -math.pi), np.minimum(lim[:, 1], math.pi)
    return rng.uniform(lo, hi, size=(count, arm.n))


def reference_fk(arm, q):
    """The numpy reference's pose of ``q`` (every row must be evaluable)."""
    T, status = serial_reference.fk(arm.description, np.atleast_2d(q))
    assert np.all(status == 0)
    return T


def rtb_dh_rows(robot):
    """roboticstoolbox's DH links as deltagen DH rows (a, alpha, d, offset, flip)."""
    rows = []
    for link in robot.links:
        row = dict(a=float(link.a), alpha=float(link.alpha), d=float(link.d))
        row["offset"] = float(link.offset)
        if link.isflip:
            row["flip"] = True
        rows.append(row)
    return rows


#: A 7-axis Puma: Corke's Puma 560 table with joint 6 turned into an offset link
#: (a6 = 0.05 m, alpha6 = 90 deg) and a 7th revolute joint behind it (d7 = 0.1 m), so that
#: axis 7 is perpendicular to axis 6 and the arm is kinematically redundant.
PUMA7_ROWS = (
    dict(a=0.0, alpha_deg=90, d=0.6718, qlim_deg=[-160, 160]),
    dict(a=0.4318, alpha=0.0, d=0.0, qlim_deg=[-45, 225]),
    dict(a=0.0203, alpha_deg=-90, d=0.15005, qlim_deg=[-225, 45]),
    dict(a=0.0, alpha_deg=90, d=0.4318, qlim_deg=[-110, 170]),
    dict(a=0.0, alpha_deg=-90, d=0.0, qlim_deg=[-100, 100]),
    dict(a=0.05, alpha_deg=90, d=0.0, qlim_deg=[-266, 266]),
    dict(a=0.0, alpha=0.0, d=0.1, qlim_deg=[-170, 170]),
)


# the DeltaRobot batched methods: (arguments, first argument q or p, outputs)
BACKENDS = ("compiled", "reference")


#: Per method: (number of array arguments, kind of input, number of outputs).
DELTA_METHODS = {
    "fk": (1, "q", 1),
    "fk_vel": (2, "q", 2),
    "fk_acc": (3, "q", 3),
    "jacobian": (1, "q", 1),
    "ik": (1, "p", 1),
    "ik_vel": (2, "p", 2),
    "ik_acc": (3, "p", 3),
}


def args_for(method, lead, width, rng=None):
    """Valid arguments of ``method`` with leading shape ``lead`` and ``width`` columns."""
    rng = rng or np.random.default_rng(0)
    n_args, kind, _ = DELTA_METHODS[method]
    size = int(np.prod(lead, dtype=int))
    if kind == "q":
        first = delta_oracles.random_q(rng, size)
    else:  # positions well inside the default robot's workspace
        first = np.column_stack(
            [
                rng.uniform(-0.1, 0.1, size),
                rng.uniform(-0.1, 0.1, size),
                rng.uniform(-0.8, -0.6, size),
            ]
        )
    arrays = [first] + [rng.normal(size=(size, 3)) for _ in range(n_args - 1)]
    if width == 4:
        arrays = [np.column_stack([a, rng.uniform(-3, 3, size)]) for a in arrays]
    return [a.reshape(tuple(lead) + (width,)) for a in arrays]


def call(robot, method, args, **kw):
    return getattr(robot, method)(*args, **kw)


def as_tuple(result):
    return result if isinstance(result, tuple) else (result,)


def urdf_link(name, mass=1.0):
    return (
        f'<link name="{name}"><inertial><origin xyz="0.02 0.01 0.05" rpy="0.1 0 0.2"/>'
        f'<mass value="{mass}"/><inertia ixx="0.01" ixy="0.001" ixz="0" iyy="0.02" iyz="0" '
        'izz="0.015"/></inertial></link>'
    )


def urdf_joint(name, kind, parent, child, xyz, axis, extra=""):
    limit = '<limit lower="-3" upper="3" effort="1" velocity="1"/>'
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="0.1 -0.2 0.3"/><axis xyz="{axis}"/>{limit}{extra}</joint>'
    )


# a URDF arm with <mimic> joints (model/coupling.py)
# j3 mimics j2 (-0.5, +0.2); the prismatic j4 mimics j3 (a mimic of a mimic: 0.1, 0.01);
# j1 and j5 are free: r = (q1, q2, q5)
MIMIC = (
    '<?xml version="1.0"?>\n<robot name="mimic_arm">\n<link name="base"/>'
    + "".join(urdf_link(f"l{i}", 1.0 + 0.2 * i) for i in range(1, 6))
    + urdf_joint("j1", "revolute", "base", "l1", "0 0 0.2", "0 0 1")
    + urdf_joint("j2", "revolute", "l1", "l2", "0.1 0 0.1", "0 1 0")
    + urdf_joint(
        "j3",
        "revolute",
        "l2",
        "l3",
        "0.3 0 0",
        "0 -1 0",
        '<mimic joint="j2" multiplier="-0.5" offset="0.2"/>',
    )
    + urdf_joint(
        "j4",
        "prismatic",
        "l3",
        "l4",
        "0.2 0 0",
        "1 0 0",
        '<mimic joint="j3" multiplier="0.1" offset="0.01"/>',
    )
    + urdf_joint("j5", "revolute", "l4", "l5", "0.05 0.02 0", "0 0 1")
    + "\n</robot>\n"
)


# Klipper's own example: config/example-rotary-delta.cfg of github.com/Klipper3d/klipper
# (the kinematics keys; pins, heaters and the extruder left out). mm and degrees.
KLIPPER_ROTARY_CFG = """\
# This file is an example config file for rotary delta style printers.
[stepper_a]
step_pin: ar54
step_distance: 0.001963495
position_endstop: 252
upper_arm_length: 170.000
lower_arm_length: 320.000

[stepper_b]
step_pin: ar60   ; inline comments are allowed
step_distance: 0.001963495

[stepper_c]
step_pin: ar46
step_distance: 0.001963495

[printer]
kinematics: rotary_delta
max_velocity: 300
max_accel: 3000
max_z_velocity: 50
shoulder_radius: 33.900
shoulder_height: 412.900

[delta_calibrate]
radius: 50
"""


# Klipper's config/example-delta.cfg (the kinematics keys), mm and degrees; stepper_c gets
# its own arm and angle to exercise the per-stepper overrides
KLIPPER_LINEAR_CFG = """\
[stepper_a]
step_pin: PF0
position_endstop: 297.05
arm_length: 333.0

[stepper_b]
step_pin: PF6

[stepper_c]
step_pin: PL3
arm_length: 334.5   # a per-stepper override
angle: 91.0

[printer]
kinematics: delta
max_velocity: 300
delta_radius: 174.75
"""


# strict C99 under ASan/UBSan: the flags the fuzz drivers of tests/c/ build with
STRICT_SANITIZED = [
    "-std=c99",
    "-pedantic",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-O0",  # instrumented modules compile ~3x faster than at -O1; the sanitizers see the same
    "-fsanitize=address,undefined",
    "-fno-sanitize-recover=all",
    "-fno-omit-frame-pointer",
]


# general 6R arms (solve/general6r.py)
def random_6r_arm(seed, name=None):
    """A 6R arm with random DH rows (seeded): no two axes parallel or meeting, in general."""
    r = np.random.default_rng(seed)
    rows = [
        dict(
            a=float(r.uniform(0.1, 0.8)),
            alpha=float(r.uniform(-np.pi, np.pi)),
            d=float(r.uniform(-0.5, 0.5)),
            offset=float(r.uniform(-1, 1)),
        )
        for _ in range(6)
    ]
    name = name or f"random6r_{seed}"
    return SerialRobot.from_dh(rows, "standard", name=name, backend="reference")


def jaco_arm(name="jaco_g"):
    """roboticstoolbox's DH model of the Kinova Jaco (reversed joints as flip)."""
    rtb = pytest.importorskip("roboticstoolbox")
    rows = rtb_dh_rows(rtb.models.DH.Jaco())
    return SerialRobot.from_dh(rows, "standard", name=name, backend="reference")


# a new arm (DH rows) built in parts (derive/serial/kernels.py PARTS)
PARTS_ROWS = [
    dict(
        a=0.3,
        alpha=0.4,
        d=0.1,
        mass=2.0,
        com=(-0.1, 0.01, 0.0),
        inertia=(0.02, 0.03, 0.02, 0, 0, 0),
    ),
    dict(
        a=0.25,
        alpha=-0.3,
        d=0.0,
        mass=1.5,
        com=(-0.1, 0.0, 0.02),
        inertia=(0.01, 0.01, 0.02, 0, 0, 0),
    ),
    dict(
        a=0.0, alpha=1.2, d=0.2, mass=0.5, com=(0.0, 0.0, 0.05), inertia=(0.01, 0.01, 0.01, 0, 0, 0)
    ),
]


# ------------------------------------------------------- generated/ snapshot checks


def generated_stems() -> list[str]:
    """The modules of generated/ (apps/generate.py module_renderers), listed without
    deriving anything."""
    from deltagen.apps import generate

    return list(generate.module_renderers())


def compare_or_update_generated(stem: str, update: bool) -> None:
    """Render the generated/ module ``stem`` alone and compare its files with the checked-in
    ``generated/<stem>.*``: a stale, missing or stray file fails with its diff, or, with
    ``update`` (pytest --update-generated, DELTAGEN_UPDATE_GENERATED=1), is rewritten (in the
    manner of SymForce's compare_or_update). Every module checked this way plus
    tests/codegen/test_generated_parallel.py's listing check is what `deltagen generate
    --check` checks."""
    from deltagen.apps import generate
    from deltagen.paths import generated_dir

    directory = generated_dir()
    rendered = generate.module_renderers()[stem]()
    assert rendered and all(name.startswith(f"{stem}.") for name in rendered), sorted(rendered)
    problems = [
        f"{name} is stray: the generator does not produce it (delete it)"
        for name in sorted(p.name for p in directory.glob(f"{stem}.*") if p.name not in rendered)
    ]
    problems += [
        p for name, text in rendered.items() if (p := generate.stale(directory / name, text))
    ]
    if problems and update:
        for name in sorted(p.name for p in directory.glob(f"{stem}.*") if p.name not in rendered):
            (directory / name).unlink()
        for name, text in rendered.items():
            (directory / name).write_text(text)
        return
    assert not problems, "\n".join(problems) + (
        "\nrun `deltagen generate` (or pytest --update-generated) and commit generated/"
    )


def update_generated(config) -> bool:
    flag = os.environ.get("DELTAGEN_UPDATE_GENERATED", "").strip().lower()
    return flag in ("1", "yes", "true", "on") or bool(config.getoption("--update-generated"))


def generated_share(part: int, parts: int) -> list[str]:
    """The serial arms' modules of generated/, dealt into ``parts`` files of about equal
    work (pytest-xdist --dist loadfile runs each file on one worker, so the renders spread
    over the workers): the largest checked-in module first, each to the lightest share
    (the size of its C stands for the cost of its derivation)."""
    from deltagen.paths import generated_dir

    arms = [stem for stem in generated_stems() if stem.startswith("serial_")]

    def size(stem):
        path = generated_dir() / f"{stem}.c"
        return path.stat().st_size if path.exists() else 0

    shares: list[list[str]] = [[] for _ in range(parts)]
    loads = [0] * parts
    for stem in sorted(arms, key=lambda stem: (-size(stem), stem)):
        lightest = loads.index(min(loads))
        shares[lightest].append(stem)
        loads[lightest] += size(stem)
    return shares[part]


def shared_object(cwd: Path, name: str, flags) -> Path:
    """The object of ``cwd/name`` compiled with ``flags`` (plus -c), built once for the
    whole test run and every pytest-xdist worker: kept in the suite's build cache under a
    key of the flags, the source and the headers it includes, built under a file lock (one
    worker compiles, the others wait and reuse it). For the big modules several drivers
    link (the Puma 560's under the sanitizers), and the strict objects of tests/c/ that
    tests/codegen/test_render_stack.py reads the frames of: every object is compiled with
    -fstack-usage (an extra output, the code is the same), its frame sizes next to it
    (``obj.with_suffix(".su")``)."""
    import fcntl

    digest = hashlib.sha256(repr((GCC, list(flags), name)).encode())
    todo, seen = [name], set()
    while todo:  # the source and the local headers it includes, transitively
        file = todo.pop()
        if file in seen or not (cwd / file).exists():
            continue
        seen.add(file)
        text = (cwd / file).read_bytes()
        digest.update(file.encode() + b"\0" + text)
        todo += re.findall(r'#\s*include\s+"([^"]+)"', text.decode())
    folder = Path(os.environ["DELTAGEN_CACHE"]) / "test-objects"
    folder.mkdir(parents=True, exist_ok=True)
    obj = folder / f"{Path(name).stem}-{digest.hexdigest()[:20]}.o"
    with open(folder / f"{obj.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not obj.exists():
            work = Path(tempfile.mkdtemp(dir=folder, prefix=f".{obj.stem}."))
            try:
                partial = work / obj.name
                flags = [*flags, "-fstack-usage", "-c"]
                compile_c([name], partial, flags=flags, cwd=cwd, libs=())
                os.replace(partial.with_suffix(".su"), obj.with_suffix(".su"))
                os.replace(partial, obj)  # last: the object marks a complete entry
            finally:
                shutil.rmtree(work, ignore_errors=True)
    return obj


def private_sources(folder: Path) -> Path:
    """``folder`` filled with a copy of generated/ and of the runtime C (every .c and .h), so
    a concurrent regeneration cannot race the compiles of a test."""
    from deltagen import paths

    for path in paths.generated_dir().glob("*.[ch]"):
        shutil.copy(path, folder / path.name)
    for path in paths.runtime_dir().glob("deltagen_*.[ch]"):
        shutil.copy(path, folder / path.name)
    return folder


# ------------------------------------------- the C on its own (tests/c/test_standalone*.py)

#: strict C99, every warning an error: what a motion-controller user's build may ask of the C
STRICT = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror"]
#: the libm functions the generated and runtime C may call (nothing else is undefined)
LIBM = {
    "cos",
    "sin",
    "tan",
    "atan",
    "atan2",
    "acos",
    "asin",
    "sqrt",
    "cbrt",
    "hypot",
    "fabs",
    "copysign",
    "fmin",
    "fmax",
    "fma",
    "pow",
    "exp",
    "log",
    "ceil",
    "floor",
    "rint",
}
#: what GCC requires of every environment, freestanding ones included ("GCC requires the
#: freestanding environment provide memcpy, memmove, memset and memcmp", GCC manual,
#: "C Language"): it may call them for copies and zero fills the C never names
GCC_REQUIRED = {"memcpy", "memmove", "memset", "memcmp"}


def strict_gcc(args, cwd):
    """Run gcc with ``args`` in ``cwd``: it must succeed and print nothing (the compiler's
    text is the assertion message)."""
    proc = subprocess.run([GCC, *args], cwd=cwd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"gcc {' '.join(map(str, args))}\n{proc.stdout}\n{proc.stderr}"
    assert proc.stderr.strip() == "", f"gcc printed diagnostics:\n{proc.stderr}"
    return proc


def core_build_flags(prefix: str) -> list[str]:
    """What native/build.py compiles a module of ``prefix`` with for the Python core (the
    extension flags -fPIC -fwrapv -DNDEBUG, then compile_flags: -O3, -march=native, vector
    math where libmvec is present), plus -pedantic -Werror: one object (helpers.shared_object)
    that tests/c/test_standalone.py holds warning-free and tests/apps/test_export.py links
    into the package built as the core is."""
    from deltagen.native.build import compile_flags
    from deltagen.native.toolchain import extension_flags

    return [*extension_flags(), *compile_flags(prefix)[0], "-pedantic", "-Werror"]


def vector_math_flags(prefix: str) -> list[str]:
    """The switches of a module's vector-math branch (native/toolchain.py compile_flags adds
    them where libmvec is present), for compiling that branch on any machine."""
    return ["-fno-math-errno", "-fopenmp-simd", f"-D{prefix.upper()}_VECTOR_MATH"]


def runtime_flags(args):
    """An arm's build flags for the runtime C, which reads no arm's VECTOR_MATH switch (so
    one runtime object serves every arm; test_runtime_reads_no_arm_switch)."""
    return [a for a in args if not (a.startswith("-DDELTAGEN_") and a.endswith("_VECTOR_MATH"))]


def c_double(x: float) -> str:
    """``x`` as a C double literal, exactly (hex float; NAN and INFINITY from math.h)."""
    if math.isnan(x):
        return "NAN"
    if math.isinf(x):
        return "INFINITY" if x > 0 else "-INFINITY"
    return float(x).hex()


def c_array(name, values, ctype="double"):
    """A ``static const`` C array of ``values`` (flattened), exact for doubles."""
    flat = np.asarray(values).ravel()
    if ctype == "double":
        body = ", ".join(c_double(float(v)) for v in flat)
    else:
        body = ", ".join(str(int(v)) for v in flat)
    return f"static const {ctype} {name}[{max(len(flat), 1)}] = {{{body or '0'}}};\n"


def runtime_sources() -> list[str]:
    """The hand-written runtime C files (codegen/runtime/deltagen_*.c)."""
    from deltagen.paths import runtime_dir

    return sorted(p.name for p in runtime_dir().glob("deltagen_*.c"))


def copy_runtime(dest: Path) -> None:
    """The hand-written runtime C (codegen/runtime/), which arm modules are compiled with."""
    from deltagen.paths import runtime_dir

    for path in runtime_dir().glob("deltagen_*.[ch]"):
        shutil.copy(path, dest)


def check_symbols(objects, cwd, allowed=LIBM):
    """Only ``allowed`` symbols (libm's by default; a libmvec vector variant ``_ZGV..._f``
    counts as ``f``) undefined besides the objects' own, and no writable global or static
    data (nm's D, B, C, G, S, V kinds). Nothing is checked where nm is missing."""
    nm = shutil.which("nm")
    if nm is None:
        return
    defined, undefined, kinds = set(), set(), set()
    for obj in objects:
        table = subprocess.run(
            [nm, str(obj)], cwd=cwd, capture_output=True, text=True, check=True
        ).stdout
        for line in table.splitlines():
            parts = line.split()
            if parts[:1] == ["U"]:
                undefined.add(re.sub(r"^_ZGV\w+?_", "", parts[1]))
            elif len(parts) == 3:
                defined.add(parts[2])
                kinds.add(parts[1])
    assert undefined - defined <= allowed, sorted(undefined - defined - allowed)
    assert not kinds & set("DdBbCGgSsVv"), sorted(kinds & set("DdBbCGgSsVv"))


def long_arm(n_joints):
    """A revolute arm of n_joints > 6 (redundant), its limits within +-170 deg."""
    from deltagen.model.serial import SerialDescription

    rows = []
    for i in range(n_joints):
        rows.append(
            dict(
                a=0.3 if i % 3 == 1 else 0.02,
                alpha_deg=(90, -90, 0)[i % 3],
                d=0.1 if i % 2 else 0.25,
                qlim_deg=[-170, 170],
            )
        )
    return SerialDescription.from_rows(rows, "standard", name=f"long{n_joints}")


def render_arm(desc, dest: Path) -> None:
    """The arm's module (codegen.serial.arm_sources) and the runtime C written to ``dest``."""
    from deltagen.codegen.serial import arm_sources

    for file_name, text in arm_sources(desc).items():
        (dest / file_name).write_text(text)
    copy_runtime(dest)


def rotation_angle(Ra, Rb):
    """Angle of Ra Rb^T from ||Ra - Rb||_F = 2 sqrt(2) sin(theta / 2) (accurate near 0)."""
    d = np.linalg.norm(Ra - Rb, axis=(-2, -1))
    return 2.0 * np.arcsin(np.clip(d / (2.0 * math.sqrt(2.0)), 0.0, 1.0))
