"""rig.campaign.runner."""
