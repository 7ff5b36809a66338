"""Compatibility alias: this module now lives at :mod:`meshopt_toolkit.kernels.distance`.

``import meshopt_toolkit.distance`` returns that module itself (monkeypatching either name
patches the same object); new code imports the new path.
"""

import sys

from .kernels import distance as _module

sys.modules[__name__] = _module
