"""vrloco_env: the simulated hands-free VR user, its sensors and (later) the Gymnasium environment.

Data flows one way: :mod:`vrloco_env.motion` (intent -> true head, skeleton, steps) ->
:mod:`vrloco_env.sensors` (head IMU, Kinect v2) -> :mod:`estimators` -> locomotion -> world.
"""

__version__ = "0.1.0"
