"""The MJCF models (one folder per robot, shared pieces in ``common/``), shipped inside the package.

``assets.path("velociroach", "scene.xml")`` resolves a file whether skitter runs from a checkout or is installed.
"""

from importlib.resources import files
from pathlib import Path

ROOT = Path(str(files(__name__)))


def path(*parts: str) -> Path:
    """The path of an asset file, relative to this folder."""
    return ROOT.joinpath(*parts)
