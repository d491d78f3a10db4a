"""Calibration adapters, one module per robot or bench rig: each replays its robot's logs through the robot's model
(envs/<robot>) and declares ``ADAPTERS`` (robot name -> adapter class) and, for a log format of its own,
``LOG_READERS``; sysid/robots.py finds them here."""
