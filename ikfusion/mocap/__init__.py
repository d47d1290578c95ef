"""Motion capture read onto the human model.

:mod:`~ikfusion.mocap.skeleton_map` maps any named BVH skeleton onto the model's segments,
:mod:`~ikfusion.mocap.from_bvh` solves a BVH clip into configurations of a body scaled to it,
and :mod:`~ikfusion.mocap.model_motion` holds a motion of the model with its kinematics
(segment poses, site positions, contact phases). Simulation (:mod:`ikfusion.sim`) builds on
these; real-data code (retarget, view, evaluate) uses them without the simulators.
"""
