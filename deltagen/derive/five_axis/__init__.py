"""5-axis NC machines (model/five_axis.py), derived symbolically: ``chain`` (the rotations,
the tool tip and tool axis in the workpiece frame, and their closed-form inverse with both
rotary branches) and ``kernels`` (fk, ik and ik_all of every layout and rotary pair).
"""
