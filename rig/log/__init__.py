"""rig.log."""
