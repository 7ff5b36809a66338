"""Compatibility alias: this module now lives at :mod:`meshopt_toolkit.kernels.triangles`.

``import meshopt_toolkit.geometry`` returns that module itself (monkeypatching either name
patches the same object); new code imports the new path.
"""

import sys

from .kernels import triangles as _module

sys.modules[__name__] = _module
