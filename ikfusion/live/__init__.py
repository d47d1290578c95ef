"""Live capture: samples streamed in, each frame solved causally, poses streamed out.

``ikfusion live`` reads samples as they arrive (a replayed recording, Lab Streaming Layer inlets
or the UDP packet format of the README), solves each frame once its samples are in and sends
every actor's pose to the outputs (MVN network streaming, VMC over OSC, an LSL outlet, the
viewer, a result folder). What the sources and the solver hand to the outputs is one
:class:`~ikfusion.live.actor_pose.ActorPose` per actor and frame.

Where things are: :mod:`.samples` and :mod:`.actor_pose` (the values in and out),
:mod:`.replay` (a recording as a source), :mod:`.frames` (samples grouped into frames with
deadlines), :mod:`.actor_stream` (one actor solved causally, frame by frame; ``solve --causal``
runs it too), :mod:`.run` (the loop), :mod:`.record` (``--record``), :mod:`.kinematics`
(poses for the outputs), :mod:`.setup` (the actors of a replay or a live source),
:mod:`.settings` (``configs/live.yaml``).
"""
