"""Calibration: replay measured logs in the model, find the effect the model lacks, fit it, report it.

``calibrate.py`` is the command; :mod:`sysid.synth` generates logs with hidden effects to test it.
"""
