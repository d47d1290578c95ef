"""Live capture: samples streamed in, each frame solved causally, poses streamed out.

``ikfusion live`` reads samples as they arrive (a replayed recording, Lab Streaming Layer inlets
or the UDP packet format of the README), solves each frame once its samples are in and sends
every actor's pose to the outputs (MVN network streaming, VMC over OSC, an LSL outlet, the
viewer, a result folder). What the sources and the solver hand to the outputs is one
:class:`~ikfusion.live.actor_pose.ActorPose` per actor and frame.
"""
