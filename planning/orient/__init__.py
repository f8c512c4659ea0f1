"""planning.orient.planner."""
