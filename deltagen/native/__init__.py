"""The compiled cores: cffi build and cache (``build``), and the Python wrappers of
the delta core (``delta``) and of each serial arm's module (``serial``), of the linear delta and tripod cores
(``linear_delta``); ``parallel``
(a batched call split across threads), ``lean`` (the one-pose fast path, with its
CPython-extension entry ``lean_ext.c``) and ``general6r`` (the compiled eigen step of the
general-6R inverse kinematics, one module for every arm); ``five_axis`` wraps the 5-axis
machines' module. The speed guards' measures:
``vectorisation`` (which loops gcc vectorises, from its own report) and ``instructions``
(instructions per point under callgrind).

``hexapod`` wraps the hexapod core (``CompiledHexapod``). ``core`` is what the delta's,
the linear delta's and tripod's, the 5-axis machines' and the hexapod's wrappers share
(``CompiledCore``: the module loaded, its struct filled, a batch across threads, the one-pose
lean path of a kernel).
``manifest`` reads the kernel manifests (generated/<module>.kernels.json: each kernel's
ports and widths) and fills the parameter structs, checked against their tables.

``toolchain`` is the one C toolchain (compiler discovery, flags, compiler runs with a timeout
and the compiler's own text, a cffi build that never changes directory, gcc's ``.su``
stack-usage lines), used by ``build``, the lean extension, the speed guards and the export;
``units`` splits a module's C into one translation unit per kernel for ``build``.

May import: ``codegen``, ``derive``, ``model``, ``geometry``, the foundation modules.
"""
