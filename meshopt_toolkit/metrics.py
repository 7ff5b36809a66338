"""Compatibility alias: this module now lives at :mod:`meshopt_toolkit.riemannian.metrics`.

``import meshopt_toolkit.metrics`` returns that module itself (monkeypatching either name
patches the same object); new code imports the new path.
"""

import sys

from .riemannian import metrics as _module

sys.modules[__name__] = _module
