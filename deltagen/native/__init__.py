"""The compiled cores: cffi build and cache (``build``), and the Python wrappers of
the delta core (``delta``) and of each serial arm's module (``serial``).

May import: ``codegen``, ``derive``, ``model``, ``geometry``, the foundation modules.
"""
