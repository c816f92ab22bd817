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
serves).

``deltagen bench`` is ``bench`` (throughput and one-pose latency) with its sections and
tools: ``bench_ik`` (inverse kinematics), ``bench_general6r`` (the general-6R solver),
``bench_load`` (cold and warm load of an arm), ``bench_families`` (the linear delta's,
the tripod's, the hexapod's and a 5-axis machine's cores beside the rotary delta's), ``bench_compare`` (``--compare REF``: this
tree beside another, in one run), ``bench_report`` (JSON, PNG and the README section) and
``timing`` (timers, repeats and tables); its subcommand and dispatch are still the bench
shim of ``deltagen/cli.py`` (``main(args)`` here).

May import: anything of deltagen except ``cli``.
"""
