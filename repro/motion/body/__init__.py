"""The body a motion drives: joint roles from names and structure, the :class:`Skeleton` and its
sizes (Eq. 1), units and up axis, the rest pose, the feet, and the pose in its root frame (the
pose clouds of Section 3.2.2)."""
