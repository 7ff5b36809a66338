"""Compatibility alias: this module now lives at :mod:`meshopt_toolkit.fem.elasticity`.

``import meshopt_toolkit.elasticity`` returns that module itself (monkeypatching either name
patches the same object); new code imports the new path.
"""

import sys

from .fem import elasticity as _module

sys.modules[__name__] = _module
