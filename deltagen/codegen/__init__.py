"""Code generation: kernel -> CSE + C99 printing (``lowering``, ``printer``) ->
Jinja rendering (``render``, with the line layout of ``layout``: at most 120 columns) of a
robot's C module (``delta``, ``serial``, ``linear_delta``: the linear delta's and the
tripod's); ``export``
writes the C package of `deltagen export` (the batched module, single-point functions and
the files around them). ``five_axis`` renders the 5-axis machines' module (one for every
layout). ``templates/`` holds layout only; ``runtime`` (a package of C
files, no Python) holds hand-written C compiled beside each module.

``hexapod`` is the hexapod's module (its kernels and the fk wrapper of
runtime/deltagen_hexapod_fk.c).

May import: ``derive``, ``model``, ``geometry``, the foundation modules.
"""
