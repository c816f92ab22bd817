"""Instructions per point of the batched kernels, counted by callgrind: a measure of their
speed that does not depend on the machine's load (valgrind's Callgrind manual: the event
``Ir``, instructions executed, is exact and repeatable for the same binary and inputs).

A generated module is compiled into a small C driver (its source: :func:`driver_source`)
that calls each kernel on fixed inputs at two batch sizes, ``POINTS``; around each call the
driver zeroes callgrind's counters and dumps them (``CALLGRIND_ZERO_STATS`` and
``CALLGRIND_DUMP_STATS_AT`` from valgrind/callgrind.h, the Callgrind manual's "Client
request reference"), so each dump holds that call's instructions, the kernel's children
(libmvec's cos and sin, the runtime's Cholesky) included. Instructions per point are
(count at POINTS[1] - count at POINTS[0]) / (POINTS[1] - POINTS[0]): the call's fixed cost
(argument checks, the first block's set-up) cancels, and both sizes are whole blocks.

The build is the project's (native/build.py: -O3, -fno-math-errno, -fopenmp-simd, the
vector-math macro, libmvec) with one change: ``-march=x86-64-v3`` (AVX2, FMA, BMI2) in
place of ``-march=native``. valgrind 3.19 does not decode AVX-512, and a fixed target makes
the counts the same on every x86-64 machine that has AVX2 (Haswell, Zen and later) instead
of depending on the CPU's own flags and tuning; what still changes them is the compiler,
glibc's libmvec and valgrind, whose versions :func:`toolchain` records.

:func:`compare` holds a measurement against a stored baseline (a dict kernel -> count).
"""

from __future__ import annotations

import functools
import hashlib
import platform
import re
import shlex
import shutil
import subprocess
from pathlib import Path

from deltagen.native import build
from deltagen.native import toolchain as tools

POINTS = (512, 1024)
MARCH = "-march=x86-64-v3"
#: room per point of every output buffer (doubles): more than any kernel writes (a 7-axis
#: arm's frames: 16 x 9)
OUTPUT_ROOM = 512
_PROTOTYPE = re.compile(r"^int (\w+)\(([^)]*)\);", re.MULTILINE)
_PARAMETER = re.compile(r"^(?P<type>.*?[\s*])(?P<name>\w+)$")


def unavailable() -> str | None:
    """Why instructions cannot be counted here (None when they can)."""
    if platform.machine() not in ("x86_64", "AMD64"):
        return f"counts are taken for x86-64 ({MARCH}); this machine is {platform.machine()}"
    if shutil.which("valgrind") is None:
        return "valgrind is not installed (Debian: apt-get install valgrind; `make sysdeps`)"
    if not Path("/usr/include/valgrind/callgrind.h").is_file():
        return "valgrind/callgrind.h is missing (it comes with Debian's valgrind package)"
    flags = _cpu_flags()
    missing = [f for f in ("avx2", "fma", "bmi2") if f not in flags]
    if missing:
        return f"the CPU lacks {', '.join(missing)}: it cannot run {MARCH} code"
    if not tools.vector_math_available():
        return "no libmvec here: the kernels' vector cos/sin are not available"
    return None


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    found = re.search(r"^flags\s*:(.*)$", text, re.MULTILINE)
    return set(found.group(1).split()) if found else set()


def _first_line(command: list[str]) -> str:
    proc = subprocess.run(command, capture_output=True, text=True, timeout=60)
    return (proc.stdout or proc.stderr).strip().splitlines()[0]


def _compiler() -> str:
    return tools.host_compiler()


def toolchain() -> dict[str, str]:
    """What the counts depend on besides the C: compiler, C library (libmvec), valgrind,
    and the flags."""
    return {
        "compiler": _first_line([_compiler(), "--version"]),
        "libc": " ".join(platform.libc_ver()),
        "valgrind": _first_line(["valgrind", "--version"]),
        "march": MARCH,
    }


def _flags(prefix: str) -> tuple[list[str], list[str]]:
    args, libraries = tools.compile_flags(prefix, "-O3")
    args = [a for a in args if not a.startswith("-march=")] + [MARCH]
    return tools.extension_flags() + args, libraries


def runtime_flags() -> list[str]:
    """The flags of the runtime's C files in a driver: the modules' (:func:`_flags`) with
    the runtime's own prefix, ``deltagen`` (native/build.py adds the ``-I`` folders)."""
    return _flags("deltagen")[0]


def signatures(cdef: str, prefix: str) -> dict[str, list[tuple[str, str]]]:
    """kernel (name without ``prefix_``) -> its parameters as (C type, name), read from a
    module's .cdef.h; kernels whose prototype spans lines (ik_newton, forward_dynamics)
    are joined first."""
    joined = re.sub(r",\s*\n\s*", ", ", cdef)
    out = {}
    for name, params in _PROTOTYPE.findall(joined):
        if not name.startswith(prefix + "_"):
            continue
        parsed = []
        for raw in params.split(","):
            found = _PARAMETER.match(raw.strip())
            if found is None:
                raise ValueError(f"{name}: cannot read the parameter {raw.strip()!r}")
            parsed.append((found.group("type").strip(), found.group("name")))
        out[name.removeprefix(prefix + "_")] = parsed
    return out


def _c_value(value) -> str:
    if isinstance(value, (list, tuple)):
        return "{" + ", ".join(_c_value(v) for v in value) + "}"
    return float(value).hex()  # C99 hexadecimal floating constant: exact


def driver_source(
    header: str,
    prefix: str,
    kernels: dict[str, list[tuple[str, str]]],
    inputs: dict[str, int],
    geometry: tuple[str, dict] | None = None,
    axes: int = 3,
) -> str:
    """The C driver (module doc): ``kernels`` as from :func:`signatures`, ``inputs`` the
    width (doubles per point) of every input array it reads from ``<dir>/<name>.f64``
    (argv[1]), ``geometry`` (struct type, fields) for a module whose kernels take one."""
    top = POINTS[-1]
    lines = [
        "#include <stdint.h>",
        "#include <stdio.h>",
        "#include <stdlib.h>",
        "#include <valgrind/callgrind.h>",
        f'#include "{header}"',
        "",
        "static double *input(const char *dir, const char *name, size_t count)",
        "{",
        "    char path[4096];",
        '    snprintf(path, sizeof path, "%s/%s.f64", dir, name);',
        '    FILE *f = fopen(path, "rb");',
        "    double *data = malloc(count * sizeof(double));",
        "    if (f == NULL || data == NULL || fread(data, sizeof(double), count, f) != count) {",
        '        fprintf(stderr, "cannot read %s\\n", path);',
        "        exit(2);",
        "    }",
        "    fclose(f);",
        "    return data;",
        "}",
        "",
        "int main(int argc, char **argv)",
        "{",
        "    if (argc != 2) {",
        '        fprintf(stderr, "usage: driver DATA_DIR\\n");',
        "        return 2;",
        "    }",
    ]
    if geometry is not None:
        struct, fields = geometry
        init = ", ".join(f".{k} = {_c_value(v)}" for k, v in fields.items())
        lines.append(f"    static const {struct} geometry = {{{init}}};")
    for name, width in inputs.items():
        lines.append(f'    const double *in_{name} = input(argv[1], "{name}", {top * width});')
    outputs = max(
        sum(1 for t, _ in params if not t.startswith("const")) for params in kernels.values()
    )
    lines.append(f"    void *out[{outputs}];")
    lines.append(f"    for (int i = 0; i < {outputs}; ++i) {{")
    lines.append(f"        out[i] = calloc({top * OUTPUT_ROOM}, sizeof(double));")
    lines.append("        if (out[i] == NULL) {")
    lines.append("            return 2;")
    lines.append("        }")
    lines.append("    }")
    for kernel, params in kernels.items():
        for size in (64, *POINTS):  # a warm-up call first (cold caches, lazy binding)
            args, o = [], 0
            for ctype, pname in params:
                if pname == "geometry":
                    args.append("&geometry")
                elif ctype == "size_t" and pname == "n":
                    args.append(str(size))
                elif ctype == "size_t" and pname == "axes":
                    args.append(str(axes))
                elif ctype.startswith("const double"):
                    if pname not in inputs:
                        raise ValueError(f"{prefix}_{kernel}: no input data named {pname!r}")
                    args.append(f"in_{pname}")
                elif ctype.endswith("*") and not ctype.startswith("const"):
                    args.append(f"({ctype})out[{o}]")
                    o += 1
                else:
                    raise ValueError(f"{prefix}_{kernel}: cannot pass {ctype} {pname}")
            call = f"{prefix}_{kernel}({', '.join(args)})"
            if size == 64:
                lines.append(f"    if ({call} != 0) {{")
                lines.append(f'        fprintf(stderr, "{kernel} failed\\n");')
                lines.append("        return 1;")
                lines.append("    }")
                continue
            lines.append("    CALLGRIND_ZERO_STATS;")
            lines.append(f"    (void){call};")
            lines.append(f'    CALLGRIND_DUMP_STATS_AT("{kernel} {size}");')
    lines += ["    return 0;", "}", ""]
    return "\n".join(lines)


def _run(command: list[str], cwd: Path, what: str, timeout: float = 600):
    proc = subprocess.run(
        command, cwd=cwd, capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL
    )
    tools.require_success(proc, command, what)
    return proc


def build_driver(source: Path, prefix: str, driver: str) -> Path:
    """The driver executable of the module ``source`` (generated C beside its header),
    compiled (the module one unit per kernel, in parallel) and cached under the build
    cache by everything that shapes it."""
    from concurrent.futures import ThreadPoolExecutor

    source = Path(source).resolve()
    text = source.read_text()
    runtime = {
        f: f.read_text() for f in build.runtime_files([text, source.with_suffix(".h").read_text()])
    }
    args, libraries = _flags(prefix)
    material = "\0".join(
        [
            text,
            source.with_suffix(".h").read_text(),
            driver,
            shlex.join(args),
            toolchain()["compiler"],
        ]
        + [f.name + "\0" + t for f, t in runtime.items()]
    )
    key = hashlib.sha256(material.encode()).hexdigest()[:20]
    target = build.usable_cache_dir() / "instruction-drivers" / f"{source.stem}_{key}"
    executable = target / "driver"
    if executable.is_file():
        return executable
    target.parent.mkdir(parents=True, exist_ok=True)
    import tempfile

    work = Path(tempfile.mkdtemp(prefix=f"{source.stem}.", dir=target.parent))
    try:
        sources = build.write_units(source, text, work)
        (work / "driver.c").write_text(driver)
        sources += [work / "driver.c"]
        include = [f"-I{source.parent}", f"-I{build.runtime_dir()}"]
        objects = [work / f"{i:03d}.o" for i in range(len(sources))]
        order = sorted(range(len(sources)), key=lambda i: -sources[i].stat().st_size)
        # the runtime's C (the damped Newton, the linear algebra) is one object per file
        # and flags in the build cache, shared by every driver (the Puma's and the UR5's):
        # its flags are the module's but for the module's own -D<PREFIX>_VECTOR_MATH, a
        # macro the runtime never reads (native/build.py runtime_flags)
        shared = runtime_flags()
        runtime_objects = [
            functools.partial(build._runtime_object, f, "-O3", work, shared)
            for f in runtime
            if f.suffix == ".c"
        ]
        tasks = [
            *runtime_objects,
            *(
                functools.partial(
                    _run,
                    [_compiler(), *args, *include, "-c", str(sources[i]), "-o", str(objects[i])],
                    work,
                    f"compiling {sources[i].name}",
                )
                for i in order
            ),
        ]
        with ThreadPoolExecutor(max_workers=build._build_jobs()) as pool:
            done = list(pool.map(lambda task: task(), tasks))
        objects += done[: len(runtime_objects)]
        _run(
            [_compiler(), *args, "-Wl,-z,now", *map(str, objects), "-o", str(work / "driver")]
            + [f"-l{lib}" for lib in libraries],
            work,
            "linking the instruction-count driver",
        )
        for path in work.iterdir():
            if path.name != "driver":
                path.unlink()
        try:
            work.replace(target)
        except OSError:  # another process published it first
            shutil.rmtree(work, ignore_errors=True)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    return executable


def count(executable: Path, data: dict, kernels) -> dict[str, dict[int, int]]:
    """Run the driver under callgrind; kernel -> {points: instructions of that call}."""
    import tempfile

    import numpy as np

    with tempfile.TemporaryDirectory(prefix="deltagen-callgrind.") as tmp:
        work = Path(tmp)
        for name, array in data.items():
            np.ascontiguousarray(array, dtype=np.float64).tofile(work / f"{name}.f64")
        _run(
            [
                "valgrind",
                "--tool=callgrind",
                "--dump-instr=no",
                "--collect-jumps=no",
                f"--callgrind-out-file={work / 'cg.out'}",
                str(executable),
                str(work),
            ],
            work,
            f"valgrind --tool=callgrind {executable.name}",
        )
        counts: dict[str, dict[int, int]] = {}
        for dump in work.glob("cg.out*"):
            text = dump.read_text()
            trigger = re.search(r"^desc: Trigger: Client Request: (\w+) (\d+)$", text, re.MULTILINE)
            total = re.search(r"^(?:totals|summary): (\d+)", text, re.MULTILINE)
            if trigger is None or total is None:
                continue  # the program's final dump
            counts.setdefault(trigger.group(1), {})[int(trigger.group(2))] = int(total.group(1))
    missing = [k for k in kernels if set(counts.get(k, {})) != set(POINTS)]
    if missing:
        raise build.BuildError(f"callgrind wrote no count for {', '.join(missing)}")
    return counts


def per_point(counts: dict[int, int]) -> float:
    """Instructions per point from one kernel's counts at the two sizes (module doc)."""
    low, high = POINTS
    return (counts[high] - counts[low]) / (high - low)


def compare(baseline: dict, measured: dict, tolerance: float = 0.05) -> list[str]:
    """Problems of ``measured`` against ``baseline`` (both {kernel: instructions per
    point}): a kernel over (1 + tolerance) x its baseline, one under (1 - tolerance) x
    (faster: the baseline must be refreshed so the next slowdown is measured from there),
    one with no baseline, and a baseline kernel not measured."""
    problems = []
    for kernel in sorted(set(baseline) | set(measured)):
        old, new = baseline.get(kernel), measured.get(kernel)
        if old is None:
            problems.append(f"{kernel}: {new:.1f} instructions per point, and no baseline")
        elif new is None:
            problems.append(f"{kernel}: in the baseline ({old:.1f}) but not measured")
        elif new > old * (1 + tolerance):
            problems.append(
                f"{kernel}: {old:.1f} -> {new:.1f} instructions per point "
                f"(+{100 * (new / old - 1):.1f} %, more than {100 * tolerance:g} %): slower"
            )
        elif new < old * (1 - tolerance):
            problems.append(
                f"{kernel}: {old:.1f} -> {new:.1f} instructions per point "
                f"({100 * (new / old - 1):.1f} %, more than {100 * tolerance:g} % fewer): "
                "faster, refresh the baseline"
            )
    return problems
