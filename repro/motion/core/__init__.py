"""The core of the motion library: the :class:`~repro.motion.core.motion.Motion` type, quaternions,
forward kinematics and the operations on clips (cut, blend, easing) every later stage uses."""
