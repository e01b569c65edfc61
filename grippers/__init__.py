"""grippers: one interface for robot grippers from different vendors."""
