"""cutlab.planning: NC language, stock models, roughing, feed post-processing, 5-axis orientation.

May import ``analysis``; never ``rig``.
"""
