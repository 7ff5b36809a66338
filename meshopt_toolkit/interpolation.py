"""Compatibility alias: this module now lives at :mod:`meshopt_toolkit.fem.interpolation`.

``import meshopt_toolkit.interpolation`` returns that module itself (monkeypatching either name
patches the same object); new code imports the new path.
"""

import sys

from .fem import interpolation as _module

sys.modules[__name__] = _module
