"""Compatibility alias: this module now lives at :mod:`meshopt_toolkit.riemannian.geodesics`.

``import meshopt_toolkit.geodesics`` returns that module itself (monkeypatching either name
patches the same object); new code imports the new path.
"""

import sys

from .riemannian import geodesics as _module

sys.modules[__name__] = _module
