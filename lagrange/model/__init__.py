"""The model: a :class:`~lagrange.model.tree.Tree` of bodies and joints (every robot, planar or 3-D), the laws of
contact and joint limits, and the checks of its parameters."""
