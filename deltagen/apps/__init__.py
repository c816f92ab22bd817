"""The CLI's jobs, one module per command, each with ``add_parser(subparsers)`` (its
argparse subcommand) and ``run(args) -> int`` (the exit status), registered in
``deltagen/cli.py``'s ``COMMANDS``: ``generate``, ``validate`` (the delta report's
trajectory), ``demos`` (`deltagen demo`), ``workspace`` (PNG slices and the 3D page of
robot.workspace), ``sweep`` (the CSV and Pareto plot of deltagen.sweep), ``kinematics``
(``fk`` and ``ik`` of one pose or a batch), ``dynamics`` (motor sizing along a trajectory),
``calibrate`` (a built delta's geometry from measured pairs) and ``export`` (a
self-contained C package for a controller, every robot family through one path). Their
helpers: ``tables`` (the one CSV/NPY reader and writer of batches, columns by name),
``plotting`` (the one module that imports matplotlib), ``hexapod`` (the hexapod's jobs of
`deltagen fk|ik|workspace`, from the per-kind ``JOBS`` tables of ``kinematics`` and
``workspace``) and ``robots``, the one loader every command takes its robot from
(``robot_of``: the kind decided from the file, the URDF options, the kinds a command
serves; ``run_job``: a command's per-kind job table at work).

``deltagen bench`` is the ``bench`` package (throughput and one-pose latency, one
measure-and-render path: each section declares what it times, one engine runs, records and
renders it; its own docstring names its modules: the sections, the engine, the timers, the
peer libraries, IK, general 6R, the other families, load, ``--compare`` and the report).

May import: anything of deltagen except ``cli``.
"""
