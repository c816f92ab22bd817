"""The CLI's jobs: ``generate``, ``validate`` (the delta report's trajectory),
``demos``, ``workspace`` (PNG slices and the 3D page of robot.workspace),
``sweep`` (the CSV and Pareto plot of deltagen.sweep), ``kinematics`` (``fk`` and ``ik``
of one pose or a batch), ``tables`` (the one CSV/NPY reader and writer of batches, columns
by name), ``dynamics`` (motor sizing along a trajectory), ``calibrate`` (a built delta's
geometry from measured pairs), ``export`` (a self-contained C package for a controller) and
``plotting`` (the one module that imports matplotlib); ``hexapod`` (`deltagen fk|ik|workspace|export`
of a hexapod robot file); ``robots`` is the one loader every
command takes its robot from (the kind decided from the file, the URDF options).

``deltagen bench`` is ``bench`` (throughput and one-pose latency) with its sections and
tools: ``bench_ik`` (inverse kinematics), ``bench_general6r`` (the general-6R solver),
``bench_load`` (cold and warm load of an arm), ``bench_families`` (the linear delta's,
the tripod's, the hexapod's and a 5-axis machine's cores beside the rotary delta's), ``bench_compare`` (``--compare REF``: this
tree beside another, in one run), ``bench_report`` (JSON, PNG and the README section) and
``timing`` (timers, repeats and tables).

May import: anything of deltagen except ``cli``.
"""
