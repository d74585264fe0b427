"""A fleet: zone control of several robots' paths (zones) and planning their tasks together (plan)."""
