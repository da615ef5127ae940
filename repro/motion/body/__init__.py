"""The body a motion drives: joint roles from names and structure, the :class:`Skeleton` and its
sizes (Eq. 1), units and up axis, the rest pose, and the feet."""
