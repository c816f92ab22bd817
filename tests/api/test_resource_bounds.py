"""Resources bounded before allocation: a workspace grid or a sweep larger than the memory
budget (DELTAGEN_MAX_MEMORY) is refused with a message naming the option and the size;
input files are read only as regular files of bounded size (DELTAGEN_MAX_INPUT); a
``--scheduler`` address that is not a Dask scheduler is refused quickly; Ctrl-C ends a
sweep with exit status 130. Cases that would allocate without bound or hang on an
unguarded build run in a subprocess with an address-space rlimit or a timeout. Names this
change adds are looked up as module attributes when a test runs, so that on a tree without
them the other tests still run and fail one by one."""

from __future__ import annotations

import os
import resource
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from helpers import REPO

from deltagen import DeltaRobot, InputError, cli, inputs
from deltagen.api import sweep as api_sweep
from deltagen.api import workspace as api_workspace
from deltagen.api.sweep import SweepError, SweepSpec

ADDRESS_SPACE = 3 << 30  # rlimit of the subprocesses: far above what they need, far below
# what an unbounded grid, sweep or /dev/zero read would take

SPEC = (
    'design = "sobol"\nn = 4\nseed = 3\n[ranges]\nr_a = [0.15, 0.25]\nr_b = 0.045\n'
    "l_a = [0.3, 0.4]\nl_b = [0.7, 0.9]\n[score]\nstep = 0.12\nenvelope_levels = 8\n"
)


def _limited():
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


def _deltagen(*argv, env=None, timeout=120):
    """`python -m deltagen argv` under the address-space rlimit."""
    return subprocess.run(
        [sys.executable, "-m", "deltagen", *argv],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=_limited,
        env={**os.environ, **(env or {})},
    )


def _run(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


# ------------------------------------------------------------------- the memory budget


def test_memory_budget_is_configurable_and_checked(monkeypatch):
    monkeypatch.setenv("DELTAGEN_MAX_MEMORY", "2M")
    assert inputs.memory_limit() == 2 << 20
    inputs.check_memory(2 << 20, "a plan", "a smaller one")  # at the limit: allowed
    with pytest.raises(InputError, match=r"a plan needs about 2 MiB .* 2 MiB allowed; smaller"):
        inputs.check_memory((2 << 20) + 1, "a plan", "smaller")
    for bad in ("lots", "-1G", "0", "1.5X"):
        monkeypatch.setenv("DELTAGEN_MAX_MEMORY", bad)
        with pytest.raises(InputError, match="DELTAGEN_MAX_MEMORY must be a size"):
            inputs.memory_limit()
    monkeypatch.delenv("DELTAGEN_MAX_MEMORY")
    assert inputs.memory_limit() >= 256 << 20


def test_voxel_counts_are_the_grid_the_workspace_builds():
    """The estimate's voxel count is the grid delta_workspace then makes (so the check
    sizes what is allocated)."""
    robot = DeltaRobot.default(backend="reference")
    g = robot.geometry
    for step in (0.09, 0.13):
        ws = robot.workspace(step, envelope=False, progress=False)
        box = api_workspace.delta_default_box(g.r_a, g.r_b, g.l_a, g.l_b)
        assert api_workspace.voxel_counts(box, step) == (ws.x.size, ws.y.size, ws.z.size)


def test_workspace_grid_beyond_the_budget_names_step_and_size(monkeypatch):
    robot = DeltaRobot.default(backend="reference")
    monkeypatch.setenv("DELTAGEN_MAX_MEMORY", "64M")
    g = robot.geometry
    nx, ny, nz = api_workspace.voxel_counts(
        api_workspace.delta_default_box(g.r_a, g.r_b, g.l_a, g.l_b), 0.005
    )
    assert (
        nx * ny * nz * api_workspace.DELTA_BYTES_PER_VOXEL > 64 << 20
    )  # the case is over the budget
    with pytest.raises(InputError, match=r"step = 0.005 m .* needs about [0-9.]+ GiB"):
        robot.workspace(0.005, progress=False)
    arm = pytest.importorskip("deltagen").SerialRobot.load("puma560", backend="reference")
    with pytest.raises(InputError, match="joint samples"):
        arm.workspace(0.1, samples=10**9, progress=False)
    with pytest.raises(InputError, match=r"step = 1e-05 m"):
        arm.workspace(1e-5, samples=2000, progress=False)


def test_cli_workspace_step_too_fine_is_refused_without_allocating(tmp_path):
    """`deltagen workspace --step 0.002` planned ~1.6e9 voxels (> 100 GB): under a 3 GiB
    address-space limit it must end with exit 2 and a message, not a MemoryError."""
    r = _deltagen(
        "workspace", "--step", "0.002", "--backend", "reference", "--out", str(tmp_path), "--quiet"
    )
    assert r.returncode == 2, r.stderr
    assert "step = 0.002 m" in r.stderr and "GiB" in r.stderr and "DELTAGEN_MAX_MEMORY" in r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize(
    "change, key",
    [
        ({"n": 10**12}, "n = 1e+12 designs"),
        ({"design": "grid", "n": 10**4}, "n = 10000 values per varied length"),
        ({"score": {"step": 1e-4}}, "score.step = 0.0001 m"),
    ],
)
def test_sweep_beyond_the_budget_is_refused_before_the_designs_are_made(change, key):
    spec = {
        "design": "sobol",
        "n": 4,
        "ranges": {"r_a": [0.15, 0.25], "r_b": 0.045, "l_a": [0.3, 0.4], "l_b": [0.7, 0.9]},
        **change,
    }
    with pytest.raises(SweepError) as info:
        SweepSpec.from_mapping(spec)
    assert key in str(info.value) and "of memory" in str(info.value)


# ------------------------------------------------------------------------ input files


def test_input_files_are_regular_files_of_bounded_size(tmp_path, monkeypatch, capsys):
    good = tmp_path / "q.csv"
    good.write_text("q1,q2,q3\n" + "0.1,0.2,0.3\n" * 20)
    assert inputs.read_regular_file(good) == good.read_bytes()
    monkeypatch.setenv("DELTAGEN_MAX_INPUT", "100")
    code, _, err = _run(capsys, "fk", "default", "--backend", "reference", "--input", str(good))
    assert code == 2 and "larger than the 100 B allowed" in err and "DELTAGEN_MAX_INPUT" in err
    monkeypatch.delenv("DELTAGEN_MAX_INPUT")
    code, _, err = _run(capsys, "fk", "default", "--backend", "reference", "--input", str(tmp_path))
    assert code == 2 and "is a directory" in err and "Traceback" not in err
    code, _, err = _run(capsys, "calibrate", "/dev/null/x")
    assert code == 2 and "cannot read" in err


@pytest.mark.parametrize(
    "argv",
    [
        ("fk", "default", "--input", "/dev/zero", "--backend", "reference"),
        ("dynamics", "default", "--input", "/dev/zero", "--backend", "reference"),
        ("calibrate", "/dev/zero", "--backend", "reference"),
        ("fk", "/dev/zero", "0", "0", "0", "--backend", "reference"),
        ("sweep", "/dev/zero", "--quiet"),
    ],
    ids=["fk", "dynamics", "calibrate", "robot", "sweep"],
)
def test_an_endless_device_is_refused_not_read(argv):
    r = _deltagen(*argv)
    assert r.returncode == 2, r.stderr
    assert "/dev/zero" in r.stderr and "is a device" in r.stderr and "Traceback" not in r.stderr


def test_a_fifo_is_refused_not_waited_on(tmp_path):
    fifo = tmp_path / "poses.csv"
    os.mkfifo(fifo)
    for argv in (("fk", "default", "--input", str(fifo)), ("fk", str(fifo), "0", "0", "0")):
        r = _deltagen(*argv, "--backend", "reference", timeout=60)
        assert r.returncode == 2, r.stderr
        assert "FIFO" in r.stderr and "Traceback" not in r.stderr


# ---------------------------------------------------------------------- Dask scheduler


class _Server:
    """A local TCP server that answers each connection with ``banner`` (None: silence)."""

    def __init__(self, banner):
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.banner = banner
        self.held = []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.held.append(conn)
            if self.banner is not None:
                try:
                    conn.sendall(self.banner)
                except OSError:
                    pass

    def close(self):
        self.sock.close()
        for c in self.held:
            c.close()


def test_probe_refuses_what_is_not_a_dask_scheduler(monkeypatch):
    banner = _Server(b"SSH-2.0-OpenSSH_9.6\r\n")
    silent = _Server(None)
    try:
        with pytest.raises(SweepError, match="not as a Dask scheduler"):
            api_sweep.probe_scheduler(banner.address, 5.0)
        with pytest.raises(SweepError, match="within 0.5 s"):
            api_sweep.probe_scheduler(silent.address, 0.5)
    finally:
        banner.close()
        silent.close()
    closed = socket.create_server(("127.0.0.1", 0))
    port = closed.getsockname()[1]
    closed.close()
    with pytest.raises(SweepError, match="cannot connect"):
        api_sweep.probe_scheduler(f"tcp://127.0.0.1:{port}", 2.0)
    with pytest.raises(SweepError, match="tcp://host:port"):
        api_sweep.probe_scheduler("tcp://nohostport", 1.0)
    monkeypatch.setenv("DELTAGEN_CONNECT_TIMEOUT", "soon")
    with pytest.raises(SweepError, match="DELTAGEN_CONNECT_TIMEOUT"):
        from deltagen.api.sweep import connect

        connect(banner.address)


def test_cli_sweep_at_a_non_dask_address_ends_quickly_without_allocating(tmp_path):
    """A banner read as Dask's frame length asked for 2.8 EiB; under a 3 GiB address-space
    limit the command ends with exit 2 and a message naming the address."""
    pytest.importorskip("dask.distributed")
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    server = _Server(b"SSH-2.0-OpenSSH_9.6 banner of another service\r\n")
    try:
        r = _deltagen(
            "sweep", str(spec), "--scheduler", server.address, "--out", str(tmp_path / "o")
        )
    finally:
        server.close()
    assert r.returncode == 2, r.stderr
    assert server.address in r.stderr and "not as a Dask scheduler" in r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "o").exists()


# --------------------------------------------------------------------------- Ctrl-C


def test_ctrl_c_ends_a_sweep_with_130_and_no_traceback(tmp_path):
    spec = tmp_path / "long.toml"
    spec.write_text(SPEC.replace("n = 4", "n = 4096").replace("step = 0.12", "step = 0.05"))
    # Ctrl-C's disposition and mask as a terminal gives them: a child inherits an ignored
    # SIGINT, and Python then never raises KeyboardInterrupt, and it inherits a blocked
    # SIGINT, which then stays pending (a library run earlier in this pytest worker may have
    # left SIGINT ignored or blocked; the full suite's workers timed out both ways)
    code = (
        "import signal, sys\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})\n"
        "from deltagen.cli import main\nprint('ready', flush=True)\n"
        "sys.exit(main(sys.argv[1:]))"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code, "sweep", str(spec), "--scheduler", "inprocess"]
        + ["--out", str(tmp_path / "o"), "--quiet"],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout.readline().strip() == "ready"
        time.sleep(1.0)  # let the sweep get under way (4096 designs take minutes)
        proc.send_signal(signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:  # say what the child did with the signal
            with open(f"/proc/{proc.pid}/status") as f:
                masks = f.read().splitlines()
            pytest.fail(
                "no exit 60 s after SIGINT: " + "; ".join(m for m in masks if m[:3] == "Sig")
            )
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert not (tmp_path / "o" / "sweep.csv").exists()


def test_numpy_grid_of_the_estimate_is_the_one_allocated():
    """DELTA_BYTES_PER_VOXEL counts at least the arrays the result holds per voxel."""
    robot = DeltaRobot.default(backend="reference")
    ws = robot.workspace(0.15, envelope=False, progress=False)
    held = sum(
        getattr(ws, k).nbytes // ws.usable.size
        for k in ("usable", "condition", "velocity_gain", "force_gain", "q")
    )
    assert held < api_workspace.DELTA_BYTES_PER_VOXEL
    assert np.all(ws.usable.shape == (ws.x.size, ws.y.size, ws.z.size))


def test_bench_batch_beyond_the_budget_is_refused(capsys):
    assert cli.main(["bench", "--n", str(10**12)]) == 2
    err = capsys.readouterr().err
    assert "--n = 1000000000000" in err and "TiB" in err and "Traceback" not in err
