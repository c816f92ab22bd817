"""Code generation: kernel -> CSE + C99 printing (``lowering``, ``printer``) ->
Jinja rendering (``render``) of a robot's C module (``delta``, ``serial``). ``templates/``
holds layout only; ``runtime/`` holds hand-written C compiled beside each module.

May import: ``derive``, ``model``, ``geometry``, the foundation modules.
"""
