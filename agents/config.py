"""The one error of a configuration a user gave: a command line, a hyperparameter file, a run folder's record or an
optimizer's run configuration. Every tool reports it in one line, naming the file, the field and the value, without
a traceback."""

from __future__ import annotations


class ConfigError(ValueError):
    """A configuration that cannot be used; the message names the file (or flag), the field and the value."""
