"""Code generation: kernel -> CSE + C99 printing (``lowering``, ``printer``) ->
Jinja rendering (``render``) of a robot's C module (``delta``, ``serial``); ``export``
writes the C package of `deltagen export` (the batched module, single-point functions and
the files around them). ``five_axis`` renders the 5-axis machines' module (one for every
layout). ``templates/`` holds layout only; ``runtime`` (a package of C
files, no Python) holds hand-written C compiled beside each module.

May import: ``derive``, ``model``, ``geometry``, the foundation modules.
"""
