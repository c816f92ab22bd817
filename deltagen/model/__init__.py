"""Robot descriptions: what a robot *is*, validated, before any math is derived.

Holds the delta geometry (``delta``), serial chains in DH / modified DH / universal
coordinates (``serial``), TOML robot files (``robot_file``), names that reach C identifiers
(``naming``) and structure detection of a chain (``structure``: central wrist, parallel
axes, planar arms), which both the derivation and the solvers read. Imports into these:
``urdf`` (a URDF chain as universal coordinates), ``coupling`` (URDF ``<mimic>`` joints,
q_j = m_j q_i + c_j) and ``klipper`` (Klipper rotary-delta printer.cfg as a delta geometry, and a linear delta's).
``linear_delta`` holds the linear delta's and the tripod's geometry.

``hexapod``: the hexapod (Stewart-Gough platform) geometry, LinuxCNC genhexkins' default
included.
``five_axis`` describes 5-axis NC machines (table-table, head-head, table-head; AC or BC).
``parameters``: the type of the per-family parameter tables (``DELTA_PARAMETERS`` and the
others: each field of a family's C parameter struct, declared once) and their reading.

May import: ``geometry`` and the foundation modules (``deltagen.errors``, ``status``,
``inputs``, ``paths``). Nothing else of deltagen.
"""
